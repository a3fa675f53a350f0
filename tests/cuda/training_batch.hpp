// The training batch the tests of stage 2's device pass share (host twin and
// device): spot's two views' pixels, two jittered rays each (a group), at the
// training settings, with an L2 loss of each pixel's mean against a varying
// grey and the clips stage 2 uses, as a share of the loss's 1/n.
#pragma once

#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <vector>

#include "difftrans/core/vec.hpp"
#include "difftrans/render/tracer.hpp"
#include "difftrans/scene/camera.hpp"

namespace dt_test {

struct TrainingBatch {
  static constexpr int group = 2;
  std::vector<float> rays;  // origin xyz, direction xyz per ray
  std::int64_t groups = 0;
  float inv_n = 1.0f;       // 1 / groups: the loss is a mean over the pixels
  float clip_geometry = 0.0f, clip_ior = 0.0f;

  // Depth 16, the whole tree to depth 8, roulette beyond, pruning at 0.01.
  static difftrans::render::TraceSettings trace() {
    difftrans::render::TraceSettings t;
    t.max_depth = 16;
    t.tree_depth = 8;
    t.roulette = true;
    t.prune_throughput = 0.01f;
    return t;
  }

  // size² pixels of each of two views of an object at the origin; `nudge`
  // moves every origin by one float step along x.
  static TrainingBatch make(int size, bool nudge = false) {
    using difftrans::Vec3f;
    TrainingBatch b;
    for (const Vec3f eye : {Vec3f(0.3f, 0.4f, 1.6f), Vec3f(-1.2f, 0.2f, -0.9f)}) {
      const auto cam = difftrans::scene::look_at_camera(eye, Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, size, size);
      for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x)
          for (int q = 0; q < group; ++q) {
            const difftrans::scene::Ray r = cam.ray_through(float(x) + 0.25f + 0.5f * float(q), float(y) + 0.5f);
            const float ox = nudge ? std::nextafter(r.origin.x, 10.0f) : r.origin.x;
            b.rays.insert(b.rays.end(), {ox, r.origin.y, r.origin.z, r.direction.x, r.direction.y, r.direction.z});
          }
    }
    b.groups = std::int64_t(b.rays.size() / 6) / group;
    b.inv_n = 1.0f / float(b.groups);
    b.clip_geometry = 2.0f * b.inv_n;
    b.clip_ior = 5.0f * b.inv_n;
    return b;
  }

  // Group j's loss 0.5 · inv_n · |mean − target|²; writes dLoss/dL for both rays.
  double loss(std::int64_t j, const difftrans::Vec3f* L, difftrans::Vec3f* dL) const {
    const difftrans::Vec3f target(0.45f + 0.2f * std::sin(0.01f * float(j)), 0.5f, 0.55f);
    const difftrans::Vec3f r = 0.5f * (L[0] + L[1]) - target;
    dL[0] = dL[1] = inv_n * r;
    return 0.5 * double(inv_n) * double(glm::dot(r, r));
  }
};

}  // namespace dt_test
