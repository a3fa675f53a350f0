// Contact sheets: the heat colour scale, the error heat map against tone-mapped
// differences, grid layout and tile placement, and the comparison sheet.
#include <doctest/doctest.h>

#include "difftrans/io/contact_sheet.hpp"

namespace io = difftrans::io;
using difftrans::Vec2i;
using difftrans::Vec3f;

namespace {
io::Image8 solid(int w, int h, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  io::Image8 t{w, h, 3, std::vector<std::uint8_t>(size_t(w) * size_t(h) * 3)};
  for (size_t p = 0; p < size_t(w) * size_t(h); ++p) {
    t.data[p * 3] = r;
    t.data[p * 3 + 1] = g;
    t.data[p * 3 + 2] = b;
  }
  return t;
}
std::array<std::uint8_t, 3> pixel(const io::Image8& im, int x, int y) {
  const size_t i = (size_t(y) * size_t(im.width) + size_t(x)) * 3;
  return {im.data[i], im.data[i + 1], im.data[i + 2]};
}
double luminance(const std::array<std::uint8_t, 3>& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }
}  // namespace

TEST_CASE("heat_color: black at 0, brightest at 1, luminance rising, clamped") {
  CHECK(io::heat_color(0.0f) == std::array<std::uint8_t, 3>{0, 0, 0});
  const auto top = io::heat_color(1.0f);
  double previous = -1.0;
  for (int i = 0; i <= 200; ++i) {
    const double l = luminance(io::heat_color(float(i) / 200.0f));
    CHECK(l >= previous);
    previous = l;
  }
  CHECK(luminance(top) > 200.0);
  CHECK(io::heat_color(7.0f) == top);
  CHECK(io::heat_color(-1.0f) == io::heat_color(0.0f));
  CHECK(io::heat_color(std::nanf("")) == io::heat_color(0.0f));
}

TEST_CASE("error_heat_map: zero where equal, scaled by the tone-mapped error") {
  io::Image a(4, 2, 0.2f), b(4, 2, 0.2f);
  b.set(1, 0, Vec3f(1.0f));  // a large error
  const float v = 0.2f;
  const int t = io::tone_map_value(v);
  b.set(3, 1, Vec3f(v));  // set to the same value: no error
  const auto heat = io::error_heat_map(a, b);
  CHECK(heat.width == 4);
  CHECK(heat.height == 2);
  CHECK(heat.channels == 3);
  CHECK(pixel(heat, 0, 0) == io::heat_color(0.0f));
  CHECK(pixel(heat, 1, 0) == io::heat_color(float(255 - t) / 255.0f / 0.25f));
  CHECK(pixel(heat, 3, 1) == io::heat_color(0.0f));
  // a different scale changes the colour of the same error
  const auto heat_wide = io::error_heat_map(a, b, 4.0f);
  CHECK(pixel(heat_wide, 1, 0) == io::heat_color(float(255 - t) / 255.0f / 4.0f));
  CHECK(pixel(heat_wide, 1, 0) != pixel(heat, 1, 0));
  CHECK_THROWS(io::error_heat_map(a, io::Image(3, 2)));
  CHECK_THROWS(io::error_heat_map(a, b, 0.0f));
}

TEST_CASE("SheetLayout: size and tile origins") {
  io::SheetLayout l;
  l.tile_width = 10;
  l.tile_height = 6;
  l.rows = 2;
  l.cols = 3;
  l.gap = 2;
  CHECK(l.width() == 3 * 10 + 4 * 2);
  CHECK(l.height() == 2 * 6 + 3 * 2);
  CHECK(l.tile_origin(0, 0) == Vec2i(2, 2));
  CHECK(l.tile_origin(1, 2) == Vec2i(2 + 2 * 12, 2 + 8));
  // the last tile ends one gap before the right and bottom edges
  const Vec2i last = l.tile_origin(l.rows - 1, l.cols - 1);
  CHECK(last.x + l.tile_width + l.gap == l.width());
  CHECK(last.y + l.tile_height + l.gap == l.height());
}

TEST_CASE("compose_sheet: every tile lands at its origin, gaps keep the background") {
  io::SheetLayout l;
  l.tile_width = 5;
  l.tile_height = 3;
  l.rows = 2;
  l.cols = 2;
  l.gap = 1;
  std::vector<std::vector<io::Image8>> tiles = {{solid(5, 3, 10, 0, 0), solid(5, 3, 20, 0, 0)},
                                                {solid(5, 3, 30, 0, 0)}};  // row 1 is short
  const auto sheet = io::compose_sheet(l, tiles, {1, 2, 3});
  CHECK(sheet.width == l.width());
  CHECK(sheet.height == l.height());
  const std::uint8_t expected[2][2] = {{10, 20}, {30, 1}};
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) {
      const Vec2i o = l.tile_origin(r, c);
      for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 5; ++x) CHECK(pixel(sheet, o.x + x, o.y + y)[0] == expected[r][c]);
    }
  CHECK(pixel(sheet, 0, 0) == std::array<std::uint8_t, 3>{1, 2, 3});
  CHECK(pixel(sheet, 6, 1) == std::array<std::uint8_t, 3>{1, 2, 3});  // between the columns
  CHECK(pixel(sheet, 3, 4) == std::array<std::uint8_t, 3>{1, 2, 3});  // between the rows
  // a tile of the wrong size, too many rows or columns
  tiles[0][1] = solid(4, 3, 0, 0, 0);
  CHECK_THROWS_WITH(io::compose_sheet(l, tiles), doctest::Contains("tile (0, 1)"));
  CHECK_THROWS(io::compose_sheet(l, {{}, {}, {}}));
  CHECK_THROWS(io::compose_sheet(l, {{solid(5, 3, 0, 0, 0), solid(5, 3, 0, 0, 0), solid(5, 3, 0, 0, 0)}}));
}

TEST_CASE("comparison_sheet: rows of truth | render | error") {
  io::Image truth(6, 4, 0.5f), render(6, 4, 0.5f);
  render.set(2, 2, Vec3f(0.0f));
  const auto sheet = io::comparison_sheet({{&truth, &render}, {&truth, &truth}}, 0.25f, 2);
  CHECK(sheet.width == 3 * 6 + 4 * 2);
  CHECK(sheet.height == 2 * 4 + 3 * 2);
  io::SheetLayout l{6, 4, 2, 3, 2};
  const auto t = io::tone_map_value(0.5f);
  CHECK(pixel(sheet, l.tile_origin(0, 0).x, l.tile_origin(0, 0).y)[0] == t);
  CHECK(pixel(sheet, l.tile_origin(0, 1).x + 2, l.tile_origin(0, 1).y + 2)[0] == 0);
  CHECK(pixel(sheet, l.tile_origin(0, 2).x + 2, l.tile_origin(0, 2).y + 2) == io::heat_color(float(t) / 255.0f / 0.25f));
  CHECK(pixel(sheet, l.tile_origin(1, 2).x + 2, l.tile_origin(1, 2).y + 2) == io::heat_color(0.0f));
  CHECK_THROWS(io::comparison_sheet({}));
}

TEST_CASE("spread_indices") {
  CHECK(io::spread_indices(10, 4) == std::vector<int>{0, 2, 5, 7});
  CHECK(io::spread_indices(3, 5) == std::vector<int>{0, 1, 2});
  CHECK(io::spread_indices(0, 5).empty());
}
