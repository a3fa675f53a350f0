// Random rays shared by the BVH tests and the BVH benchmark.
#pragma once

#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "difftrans/core/vec.hpp"

namespace dt_test {

// A uniformly distributed unit vector.
inline difftrans::Vec3f random_unit(std::mt19937& rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (;;) {
    const difftrans::Vec3f v(n(rng), n(rng), n(rng));
    const float l = glm::length(v);
    if (l > 1e-3f) return v / l;
  }
}

struct IncoherentRay {
  difftrans::Vec3f o, d;
  float tnear = 0.0f, tfar = std::numeric_limits<float>::infinity();
};

// Incoherent rays about the unit box: even ones from a sphere of radius 1.2
// towards random points in the box (mostly hits, some grazing, some misses),
// odd ones from random points inside it in random directions; with `windows`,
// every fourth (i % 4 == 1) gets a random [tnear, tfar].
inline std::vector<IncoherentRay> incoherent_rays(int n, std::uint32_t seed, bool windows) {
  using difftrans::Vec3f;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f), w(0.0f, 1.0f);
  std::vector<IncoherentRay> rays(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    IncoherentRay& r = rays[std::size_t(i)];
    if (i % 2 == 0) {
      r.o = 1.2f * random_unit(rng);
      r.d = glm::normalize(Vec3f(u(rng), u(rng), u(rng)) - r.o);
    } else {
      r.o = 0.8f * Vec3f(u(rng), u(rng), u(rng));
      r.d = random_unit(rng);
    }
    if (windows && i % 4 == 1) {
      r.tnear = 0.6f * w(rng);
      r.tfar = r.tnear + 1.5f * w(rng);
    }
  }
  return rays;
}

}  // namespace dt_test
