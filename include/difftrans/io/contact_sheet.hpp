// Pictures for people to look at: an error heat map of a render against the
// ground truth, and contact sheets (grids of equal-size 8-bit tiles), e.g. one
// row per view with ground truth | render | error.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/io/png.hpp"

namespace difftrans::io {

// Colour of t in [0, 1] (clamped; NaN as 0) on a dark-to-bright scale:
// black, purple, red, orange, pale yellow, piecewise linear between those five
// stops. Luminance rises with t, so the map reads in grey as well.
inline std::array<std::uint8_t, 3> heat_color(float t) {
  static const float stops[5][3] = {
      {0, 0, 0}, {90, 20, 120}, {200, 50, 80}, {250, 150, 20}, {255, 255, 190}};
  if (!(t > 0.0f)) t = 0.0f;
  if (t > 1.0f) t = 1.0f;
  const float x = t * 4.0f;
  const int i = std::min(3, int(x));
  const float f = x - float(i);
  std::array<std::uint8_t, 3> c{};
  for (int k = 0; k < 3; ++k)
    c[size_t(k)] = std::uint8_t(std::lround(stops[i][k] + (stops[i + 1][k] - stops[i][k]) * f));
  return c;
}

// Per pixel: the mean over RGB of |tone_map(a) − tone_map(b)| / 255 (the
// error PSNR measures, in [0, 1]) drawn with heat_color(error / scale): an
// error of `scale` or more is the brightest colour. A fixed scale (default
// 0.25) keeps sheets of different runs comparable.
inline Image8 error_heat_map(const Image& a, const Image& b, float scale = 0.25f) {
  if (a.width != b.width || a.height != b.height)
    throw std::invalid_argument("error_heat_map: sizes differ (" + std::to_string(a.width) + " x " +
                                std::to_string(a.height) + " and " + std::to_string(b.width) + " x " +
                                std::to_string(b.height) + ")");
  if (!(scale > 0.0f)) throw std::invalid_argument("error_heat_map: scale must be positive");
  const auto ta = tone_map(a), tb = tone_map(b);
  Image8 out{a.width, a.height, 3, std::vector<std::uint8_t>(a.pixel_count() * 3)};
  for (size_t p = 0; p < a.pixel_count(); ++p) {
    int sum = 0;
    for (int c = 0; c < 3; ++c) sum += std::abs(int(ta[p * 3 + size_t(c)]) - int(tb[p * 3 + size_t(c)]));
    const auto colour = heat_color(float(sum) / (3.0f * 255.0f) / scale);
    for (int c = 0; c < 3; ++c) out.data[p * 3 + size_t(c)] = colour[size_t(c)];
  }
  return out;
}

// A linear image as an 8-bit RGB tile (docs/conventions.md tone mapping).
inline Image8 tone_mapped_tile(const Image& image) { return {image.width, image.height, 3, tone_map(image)}; }

// A mask as an 8-bit RGB tile: white inside, black outside.
inline Image8 mask_tile(const Mask& mask) {
  Image8 out{mask.width, mask.height, 3, std::vector<std::uint8_t>(mask.inside.size() * 3)};
  for (size_t i = 0; i < mask.inside.size(); ++i)
    for (int c = 0; c < 3; ++c) out.data[i * 3 + size_t(c)] = mask.inside[i] ? 255 : 0;
  return out;
}

// rows x cols tiles of tile_width x tile_height pixels, `gap` pixels of
// background around and between them.
struct SheetLayout {
  int tile_width = 0, tile_height = 0;
  int rows = 0, cols = 0;
  int gap = 4;

  int width() const { return cols * tile_width + (cols + 1) * gap; }
  int height() const { return rows * tile_height + (rows + 1) * gap; }
  // Top-left pixel (x, y) of the tile in row r, column c.
  Vec2i tile_origin(int r, int c) const { return {gap + c * (tile_width + gap), gap + r * (tile_height + gap)}; }
};

// Draws the tiles into one RGB image: tiles[r][c] goes to row r, column c (a
// row may be shorter than cols; an empty tile, width 0, is left as
// background). Tiles are RGB (3 channels) of the layout's tile size; anything
// else is std::invalid_argument.
inline Image8 compose_sheet(const SheetLayout& layout, const std::vector<std::vector<Image8>>& tiles,
                            std::array<std::uint8_t, 3> background = {40, 40, 40}) {
  if (layout.tile_width <= 0 || layout.tile_height <= 0 || layout.rows <= 0 || layout.cols <= 0 || layout.gap < 0)
    throw std::invalid_argument("compose_sheet: the layout is empty");
  if (int(tiles.size()) > layout.rows) throw std::invalid_argument("compose_sheet: more rows of tiles than the layout has");
  const int w = layout.width(), h = layout.height();
  Image8 sheet{w, h, 3, std::vector<std::uint8_t>(size_t(w) * size_t(h) * 3)};
  for (size_t p = 0; p < size_t(w) * size_t(h); ++p)
    for (int c = 0; c < 3; ++c) sheet.data[p * 3 + size_t(c)] = background[size_t(c)];
  for (size_t r = 0; r < tiles.size(); ++r) {
    if (int(tiles[r].size()) > layout.cols)
      throw std::invalid_argument("compose_sheet: row " + std::to_string(r) + " has more tiles than the layout's columns");
    for (size_t c = 0; c < tiles[r].size(); ++c) {
      const Image8& t = tiles[r][c];
      if (t.width == 0) continue;
      if (t.width != layout.tile_width || t.height != layout.tile_height || t.channels != 3 ||
          t.data.size() != size_t(t.width) * size_t(t.height) * 3)
        throw std::invalid_argument("compose_sheet: tile (" + std::to_string(r) + ", " + std::to_string(c) + ") is " +
                                    std::to_string(t.width) + " x " + std::to_string(t.height) + " x " +
                                    std::to_string(t.channels) + ", expected " + std::to_string(layout.tile_width) +
                                    " x " + std::to_string(layout.tile_height) + " x 3");
      const Vec2i o = layout.tile_origin(int(r), int(c));
      for (int y = 0; y < t.height; ++y)
        std::copy_n(t.data.begin() + std::ptrdiff_t(size_t(y) * size_t(t.width) * 3), size_t(t.width) * 3,
                    sheet.data.begin() + std::ptrdiff_t((size_t(o.y + y) * size_t(w) + size_t(o.x)) * 3));
    }
  }
  return sheet;
}

// One row per view: ground truth | render | error heat map.
struct SheetRow {
  const Image* truth;
  const Image* render;
};

inline Image8 comparison_sheet(const std::vector<SheetRow>& rows, float error_scale = 0.25f, int gap = 4) {
  if (rows.empty()) throw std::invalid_argument("comparison_sheet: no rows");
  SheetLayout layout;
  layout.tile_width = rows.front().truth->width;
  layout.tile_height = rows.front().truth->height;
  layout.rows = int(rows.size());
  layout.cols = 3;
  layout.gap = gap;
  std::vector<std::vector<Image8>> tiles;
  for (const auto& r : rows)
    tiles.push_back({tone_mapped_tile(*r.truth), tone_mapped_tile(*r.render), error_heat_map(*r.render, *r.truth, error_scale)});
  return compose_sheet(layout, tiles);
}

// At most `count` indices spread evenly over [0, n): 0, then about n / count apart.
inline std::vector<int> spread_indices(int n, int count) {
  std::vector<int> out;
  if (n <= 0 || count <= 0) return out;
  const int k = std::min(n, count);
  for (int i = 0; i < k; ++i) out.push_back(int((long long)(i) * n / k));
  return out;
}

}  // namespace difftrans::io
