// A procedural box room: the near-field environment of `difftrans synth
// --room`. Rays from inside hit its walls analytically (ray–box); each wall
// has its own pattern and colours, and two emissive panels light the scene.
#pragma once

#include "difftrans/ad/glm.hpp"

namespace difftrans::scene {

// The box [centre − half, centre + half]³. Walls, as seen from inside
// (coordinates relative to the centre):
//   floor   (−y) checkerboard, cells of 1, light grey / dark blue-grey
//   ceiling (+y) plain light grey with an emissive panel |x|, |z| < 1
//   −x      checkerboard in (z, y), cells of 0.75, green / pale green
//   +x      vertical stripes along z, width 0.5, brick red / cream
//   −z      diagonal stripes (x + y), width 0.7, orange / teal, with an
//           emissive panel x ∈ [−1, 1], y ∈ [−0.5, 1.5]
//   +z      horizontal stripes along y, width 0.6, blue / yellow
// Each wall's pattern is dimmed by up to 25 % towards its lower edge, so
// that no two points of a wall look alike far apart.
struct Room {
  Vec3f centre{0.0f};
  float half = 4.0f;
  Vec3f panel_radiance{6.0f, 5.5f, 4.5f};    // on the −z wall
  Vec3f ceiling_radiance{4.0f, 4.0f, 4.0f};  // on the ceiling

  // Which wall (0: −x, 1: +x, 2: −y, 3: +y, 4: −z, 5: +z) and where the ray
  // leaves the box; false when the box lies behind the ray.
  DT_HOST_DEVICE bool exit_point(const Vec3f& o, const Vec3f& d, int& wall, Vec3f& p) const {
    float t_exit = 3.0e38f;
    wall = -1;
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0.0f) continue;
      const float bound = d[a] > 0.0f ? centre[a] + half : centre[a] - half;
      const float t = (bound - o[a]) / d[a];
      if (t < t_exit) {
        t_exit = t;
        wall = 2 * a + (d[a] > 0.0f ? 1 : 0);
      }
    }
    if (wall < 0 || !(t_exit > 0.0f)) return false;
    p = o + d * t_exit - centre;
    return true;
  }

  // The wall's radiance at a point p on it (relative to the centre).
  DT_HOST_DEVICE Vec3f wall_radiance(int wall, const Vec3f& p) const {
    const auto parity = [](float a, float cell) { return (int(floor(a / cell)) & 1) != 0; };
    const auto pick = [](bool first, const Vec3f& a, const Vec3f& b) { return first ? a : b; };
    const float shade = 0.75f + 0.25f * (p.y + half) / (2.0f * half);
    switch (wall) {
      case 0:
        return shade * pick(parity(p.z, 0.75f) != parity(p.y, 0.75f), Vec3f(0.10f, 0.50f, 0.20f), Vec3f(0.80f, 0.90f, 0.80f));
      case 1: return shade * pick(parity(p.z, 0.5f), Vec3f(0.70f, 0.15f, 0.10f), Vec3f(0.90f, 0.85f, 0.70f));
      case 2: {
        const float s = 0.75f + 0.25f * (p.z + half) / (2.0f * half);  // the floor shades along z instead
        return s * pick(parity(p.x, 1.0f) != parity(p.z, 1.0f), Vec3f(0.80f, 0.80f, 0.75f), Vec3f(0.15f, 0.15f, 0.25f));
      }
      case 3:
        if (abs(p.x) < 1.0f && abs(p.z) < 1.0f) return ceiling_radiance;
        return Vec3f(0.60f, 0.60f, 0.60f);
      case 4:
        if (abs(p.x) <= 1.0f && p.y >= -0.5f && p.y <= 1.5f) return panel_radiance;
        return shade * pick(parity(p.x + p.y, 0.7f), Vec3f(0.90f, 0.45f, 0.10f), Vec3f(0.10f, 0.50f, 0.50f));
      default: return shade * pick(parity(p.y, 0.6f), Vec3f(0.10f, 0.20f, 0.60f), Vec3f(0.90f, 0.80f, 0.20f));
    }
  }

  // Radiance arriving at o (inside the room) from direction d (need not be unit).
  DT_HOST_DEVICE Vec3f radiance(const Vec3f& o, const Vec3f& d) const {
    int wall;
    Vec3f p;
    if (!exit_point(o, d, wall, p)) return Vec3f(0.0f);
    return wall_radiance(wall, p);
  }
  DT_HOST_DEVICE Vec3f operator()(const Vec3f& o, const Vec3f& d) const { return radiance(o, d); }
};

}  // namespace difftrans::scene
