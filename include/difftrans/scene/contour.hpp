// Which points of a surface the masks pin down: for each point, the number of
// views in which it projects onto (within a band of) its mask's outline.
//
// A silhouette fixes the surface only along the contour it casts, the rim
// where the view ray grazes the surface; a point that never lies on any
// view's rim (inside a concavity, or facing every camera) is free as far as
// the masks go, and a mesh fitted to masks alone may be wrong there by any
// amount the masks cannot see. The count says how much a mask-fitted point
// can be trusted: a refinement from colour that moves a point pinned by many
// views is more likely a trade against a wrong material than a correction.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "difftrans/scene/camera.hpp"

namespace difftrans::scene {

// One view's camera and its object mask (width·height of the camera, row 0
// at the top, non-zero inside the object).
struct SilhouetteView {
  Camera camera;
  const std::uint8_t* mask = nullptr;
};

// The distance in pixels from the continuous pixel point (px, py) to the
// outline of `mask` (the pixel edges between an inside and an outside pixel,
// both in the image: where the object meets the image's border its outline
// is the frame's, not the object's), searched within `radius` pixels; a value
// above `radius` when no outline edge lies that near.
inline float distance_to_outline(const std::uint8_t* mask, int width, int height, float px, float py,
                                 float radius) {
  const auto in_image = [&](int x, int y) { return x >= 0 && y >= 0 && x < width && y < height; };
  const auto inside = [&](int x, int y) { return mask[std::size_t(y) * std::size_t(width) + std::size_t(x)] != 0; };
  // distance from (px, py) to the unit edge from (x0, y0) along x (horizontal) or y (vertical)
  const auto to_edge = [&](float x0, float y0, bool horizontal) {
    const float dx = horizontal ? px - std::clamp(px, x0, x0 + 1.0f) : px - x0;
    const float dy = horizontal ? py - y0 : py - std::clamp(py, y0, y0 + 1.0f);
    return std::sqrt(dx * dx + dy * dy);
  };
  const int r = int(std::ceil(radius)) + 1;
  const int x_lo = int(std::floor(px)) - r, x_hi = int(std::floor(px)) + r;
  const int y_lo = int(std::floor(py)) - r, y_hi = int(std::floor(py)) + r;
  float best = radius + 1.0f;
  for (int y = y_lo; y <= y_hi; ++y)
    for (int x = x_lo; x <= x_hi; ++x) {
      if (!in_image(x, y)) continue;
      const bool here = inside(x, y);
      // the edge on the pixel's left (x, y..y+1) and the one above it (x..x+1, y)
      if (in_image(x - 1, y) && here != inside(x - 1, y)) best = std::min(best, to_edge(float(x), float(y), false));
      if (in_image(x, y - 1) && here != inside(x, y - 1)) best = std::min(best, to_edge(float(x), float(y), true));
    }
  return best;
}

// For each point (flat x, y, z), the number of views in which it lies in
// front of the camera, projects inside the image and lies within `band`
// pixels of the mask's outline. Visibility is not tested: a point behind the
// rim projects onto the outline only where the surface folds back on itself,
// and a point so near the rim that it falls within the band is held by the
// same silhouette.
inline std::vector<int> contour_views(const std::vector<float>& positions, const std::vector<SilhouetteView>& views,
                                      float band = 1.0f) {
  std::vector<int> count(positions.size() / 3, 0);
  for (const SilhouetteView& v : views) {
    if (!v.mask) continue;
    const Camera& c = v.camera;
    for (std::size_t i = 0; i < count.size(); ++i) {
      const Projection<float> p = c.project(Vec3f(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]));
      if (!p.valid || p.pixel.x < 0.0f || p.pixel.y < 0.0f || p.pixel.x > float(c.width) ||
          p.pixel.y > float(c.height))
        continue;
      if (distance_to_outline(v.mask, c.width, c.height, p.pixel.x, p.pixel.y, band) <= band) ++count[i];
    }
  }
  return count;
}

}  // namespace difftrans::scene
