// Box averages of an equirectangular map over any rectangle of texel
// coordinates in constant time, from a table of running sums (a summed-area
// table) kept in double. render/footprint.hpp averages the map over the image
// of a sample's stratum with it.
//
// Texel coordinates: x = u · width, y = v · height (scene/envmap.hpp's uv),
// so texel (col, row) covers [col, col + 1] × [row, row + 1] and is centred
// at (col + 0.5, row + 0.5). The box average integrates the map held
// constant over each texel. A box one texel wide in x and y centred anywhere
// gives exactly the bilinear lookup of envmap.hpp at that point (a unit box
// over a piecewise-constant row is the linear interpolation between texel
// centres), so a footprint never smaller than a texel agrees with the point
// lookup as the footprint shrinks. x wraps around (the seam); y is clamped:
// a box reaching past a pole is slid back inside the map, which is what the
// bilinear lookup's clamp does within half a texel of the pole.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "difftrans/core/platform.hpp"
#include "difftrans/core/vec.hpp"

namespace difftrans::scene {

// A view of the running sums: (width + 1) × (height + 1) corners, 3 doubles
// each; sums[(y · (width + 1) + x) · 3 + c] = the sum of channel c over the
// texels with col < x and row < y.
struct EnvBoxTable {
  const double* sums = nullptr;
  int width = 0, height = 0;
};

// The running sums of a width × height RGB map (flat, row 0 at the top).
inline std::vector<double> env_box_sums(const float* texels, int width, int height) {
  const std::size_t stride = std::size_t(width) + 1;
  std::vector<double> sums(stride * (std::size_t(height) + 1) * 3, 0.0);
  for (int row = 0; row < height; ++row) {
    double run[3] = {0.0, 0.0, 0.0};  // this row's texels left of the corner
    for (int col = 0; col < width; ++col) {
      const std::size_t below = ((std::size_t(row) + 1) * stride + std::size_t(col) + 1) * 3;
      const std::size_t above = (std::size_t(row) * stride + std::size_t(col) + 1) * 3;
      for (int c = 0; c < 3; ++c) {
        run[c] += double(texels[(std::size_t(row) * std::size_t(width) + std::size_t(col)) * 3 + std::size_t(c)]);
        sums[below + std::size_t(c)] = sums[above + std::size_t(c)] + run[c];
      }
    }
  }
  return sums;
}

namespace detail {

// The integral of the map over [0, x] × [0, y], x in [0, width], y in
// [0, height]: the bilinear interpolation of the corner sums, which is exact
// for a map constant over each texel.
DT_HOST_DEVICE inline void env_box_integral(const EnvBoxTable& t, double x, double y, double out[3]) {
  const int stride = t.width + 1;
  int x0 = int(floor(x)), y0 = int(floor(y));
  x0 = x0 < 0 ? 0 : (x0 >= t.width ? t.width - 1 : x0);
  y0 = y0 < 0 ? 0 : (y0 >= t.height ? t.height - 1 : y0);
  const double a = x - double(x0), b = y - double(y0);
  const double* s00 = t.sums + (std::size_t(y0) * std::size_t(stride) + std::size_t(x0)) * 3;
  const double* s01 = s00 + 3;                           // x0 + 1
  const double* s10 = s00 + std::size_t(stride) * 3;     // y0 + 1
  const double* s11 = s10 + 3;
  for (int c = 0; c < 3; ++c)
    out[c] = (1 - a) * (1 - b) * s00[c] + a * (1 - b) * s01[c] + (1 - a) * b * s10[c] + a * b * s11[c];
}

// The same for any x: whole turns around the seam add whole rows.
DT_HOST_DEVICE inline void env_box_integral_wrapped(const EnvBoxTable& t, double x, double y, double out[3]) {
  const double turns = floor(x / double(t.width));
  double full[3];
  env_box_integral(t, double(t.width), y, full);
  env_box_integral(t, x - turns * double(t.width), y, out);
  for (int c = 0; c < 3; ++c) out[c] += turns * full[c];
}

}  // namespace detail

// The mean of the map over the box centred at texel coordinates (x, y) with
// half-extents (hx, hy), each at least half a texel (see the header); a box
// wider than the map goes round it (each whole turn adds a whole row), a
// box taller than the map covers it all. Non-finite input: zero.
DT_HOST_DEVICE inline Vec3f env_box_average(const EnvBoxTable& t, float x, float y, float hx, float hy) {
  if (t.width < 1 || t.height < 1 || !isfinite(x) || !isfinite(y) || !isfinite(hx) || !isfinite(hy))
    return Vec3f(0.0f);
  const double H = double(t.height);
  const double half_x = hx > 0.5f ? double(hx) : 0.5;
  double half_y = hy > 0.5f ? double(hy) : 0.5;
  if (half_y > 0.5 * H) half_y = 0.5 * H;
  double y0 = double(y) - half_y, y1 = double(y) + half_y;
  if (y0 < 0.0) y1 -= y0, y0 = 0.0;  // slid back inside at the poles
  if (y1 > H) y0 -= y1 - H, y1 = H;
  if (y0 < 0.0) y0 = 0.0;
  const double x0 = double(x) - half_x, x1 = double(x) + half_x;
  double a[3], b[3], c[3], d[3];
  detail::env_box_integral_wrapped(t, x1, y1, a);
  detail::env_box_integral_wrapped(t, x0, y1, b);
  detail::env_box_integral_wrapped(t, x1, y0, c);
  detail::env_box_integral_wrapped(t, x0, y0, d);
  const double inv_area = 1.0 / ((x1 - x0) * (y1 - y0));
  return Vec3f(float((a[0] - b[0] - c[0] + d[0]) * inv_area), float((a[1] - b[1] - c[1] + d[1]) * inv_area),
               float((a[2] - b[2] - c[2] + d[2]) * inv_area));
}

}  // namespace difftrans::scene
