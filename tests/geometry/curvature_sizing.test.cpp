// Curvature sizing: the curvature of spheres of two radii (and the edge
// lengths it asks for), of a sphere with radial noise at the scale of an edge
// (the upper quartile of the normals' turning stays near 1 / r), and of a
// torus's tube (the largest curvature, not the mean).
#include "difftrans/geometry/curvature_sizing.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <random>
#include <vector>

#include "support/shapes.hpp"

using namespace difftrans::geometry;
using glm::vec3;

namespace {

double median(std::vector<float> v) {
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
  return double(v[v.size() / 2]);
}

vec3 vertex(const std::vector<float>& p, std::size_t i) { return vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]); }

}  // namespace

TEST_CASE("curvature sizing: the curvature of spheres and a torus's tube, with and without noise") {
  CurvatureSizing o;
  o.min_length = 0.01f;
  o.max_length = 1.0f;
  o.tolerance = 1e-3f;
  for (const float r : {0.5f, 2.0f}) {
    const dt_test::Shape s = dt_test::make_icosphere(r, 4);
    const CurvatureSizingResult c = curvature_sizing(s.positions, s.triangles, o);
    INFO("radius " << r);
    for (float k : c.curvature) CHECK(k == doctest::Approx(1.0f / r).epsilon(0.05));
    // L = sqrt(6 tol / κ − 3 tol²), within [min, max]
    const float expect = std::clamp(std::sqrt(6.0f * o.tolerance * r - 3.0f * o.tolerance * o.tolerance),
                                    o.min_length, o.max_length);
    for (float l : c.length) CHECK(l == doctest::Approx(expect).epsilon(0.05));
  }
  // vertex-scale radial noise (a sixth of an edge, as a FlexiCubes sphere
  // has): the upper quartile of the normals' turning stays near 1 / r where
  // the largest would not
  dt_test::Shape noisy = dt_test::make_icosphere(0.5f, 4);
  std::mt19937 rng(7);
  std::normal_distribution<float> jitter(0.0f, 1.0f);
  const float edge = 0.5f * 1.05f / 16.0f;  // about an icosphere's edge at 4 levels
  for (std::size_t i = 0; i < noisy.positions.size(); i += 3) {
    const vec3 p = vertex(noisy.positions, i / 3);
    const vec3 q = p * (1.0f + jitter(rng) * edge / 6.0f / 0.5f);
    noisy.positions[i] = q.x;
    noisy.positions[i + 1] = q.y;
    noisy.positions[i + 2] = q.z;
  }
  const CurvatureSizingResult c = curvature_sizing(noisy.positions, noisy.triangles, o);
  MESSAGE("noisy sphere of radius 0.5: median curvature " << median(c.curvature));
  CHECK(median(c.curvature) == doctest::Approx(2.0).epsilon(0.3));
  // a torus's tube (radius 0.3) curves 3.3 around it: the quartile measures
  // the largest curvature, not the mean
  const dt_test::Shape t = dt_test::make_torus(96, 32, 1.0f, 0.3f);
  const CurvatureSizingResult ct = curvature_sizing(t.positions, t.triangles, o);
  MESSAGE("torus, tube radius 0.3: median curvature " << median(ct.curvature));
  CHECK(median(ct.curvature) > 0.8 / 0.3);
  CHECK(median(ct.curvature) < 1.3 / 0.3);
}

