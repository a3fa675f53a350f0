// The answer of every intersector (Embree on the host, the portable BVH on
// host and device): which triangle, how far, and the barycentrics there.
#pragma once

#include <cstdint>
#include <limits>

#include "difftrans/core/platform.hpp"

namespace difftrans::accel {

// point = (1 − u − v) p0 + u p1 + v p2 on triangle `prim` (−1: no hit).
struct RayHit {
  std::int32_t prim = -1;
  float t = std::numeric_limits<float>::infinity();
  float u = 0, v = 0;
  DT_HOST_DEVICE bool hit() const { return prim >= 0; }
};

}  // namespace difftrans::accel
