// Pictures of a mesh with vertex colours: six cameras frame the mesh whole,
// the colour is the vertex colours' (shaded by how the surface faces the
// viewer), +X is on the right seen from the front, the background elsewhere.
#include "difftrans/render/mesh_picture.hpp"

#include <doctest/doctest.h>

#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "support/shapes.hpp"

namespace dr = difftrans::render;

namespace {

struct Picture {
  std::vector<float> positions;
  std::vector<std::int32_t> triangles;
};

// An icosphere of radius 0.5 centred at (1, 2, 3).
Picture sphere() {
  const dt_test::Shape s = dt_test::make_icosphere(0.5f, 4);
  Picture p{s.positions, s.triangles};
  for (std::size_t i = 0; i < p.positions.size(); i += 3) p.positions[i] += 1.0f, p.positions[i + 1] += 2.0f, p.positions[i + 2] += 3.0f;
  return p;
}

const std::uint8_t* pixel(const difftrans::io::Image8& im, int x, int y) {
  return &im.data[3 * (std::size_t(y) * std::size_t(im.width) + std::size_t(x))];
}

}  // namespace

TEST_CASE("vertex_colour_picture: the sphere whole and centred from six sides, its colour where it faces the viewer") {
  const Picture m = sphere();
  const std::vector<dr::VertexColour> colours(m.positions.size() / 3, dr::VertexColour{200, 100, 50});
  const auto cams = dr::cameras_around(m.positions, 96);
  REQUIRE(cams.size() == 6);
  for (const auto& cam : cams) {
    const difftrans::io::Image8 im = dr::vertex_colour_picture(m.positions, m.triangles, colours, cam, {0, 0, 0});
    REQUIRE(im.width == 96);
    REQUIRE(im.height == 96);
    REQUIRE(im.channels == 3);
    // at the centre the surface faces the viewer: the vertices' colour (shade ~1)
    const std::uint8_t* c = pixel(im, 48, 48);
    CHECK(std::abs(int(c[0]) - 200) <= 4);
    CHECK(std::abs(int(c[1]) - 100) <= 3);
    CHECK(std::abs(int(c[2]) - 50) <= 2);
    // the border is background: the whole sphere inside the frame
    int covered = 0, border = 0;
    for (int y = 0; y < 96; ++y)
      for (int x = 0; x < 96; ++x) {
        const std::uint8_t* p = pixel(im, x, y);
        const bool lit = p[0] || p[1] || p[2];
        covered += lit;
        if (x == 0 || y == 0 || x == 95 || y == 95) border += lit;
      }
    CHECK(border == 0);
    // a ball of radius 0.5 in its bounding box's bounding sphere (0.866) at a 30° field of view: ~25 % of the pixels
    const double fraction = double(covered) / (96.0 * 96.0);
    CHECK(fraction > 0.2);
    CHECK(fraction < 0.3);
  }
}

TEST_CASE("vertex_colour_picture: seen from the front, +X is on the right and +Y up") {
  const Picture m = sphere();
  std::vector<dr::VertexColour> colours;
  for (std::size_t i = 0; i < m.positions.size(); i += 3)
    colours.push_back(m.positions[i] > 1.0f ? dr::VertexColour{255, 0, 0}
                      : m.positions[i + 1] > 2.0f ? dr::VertexColour{0, 255, 0}
                                                  : dr::VertexColour{0, 0, 255});
  const auto front = dr::cameras_around(m.positions, 64)[0];
  const difftrans::io::Image8 im = dr::vertex_colour_picture(m.positions, m.triangles, colours, front);
  const std::uint8_t* right = pixel(im, 40, 32);
  const std::uint8_t* upper_left = pixel(im, 26, 24);
  const std::uint8_t* lower_left = pixel(im, 26, 40);
  CHECK(right[0] > 2 * (right[1] + right[2]));
  CHECK(upper_left[1] > 2 * (upper_left[0] + upper_left[2]));
  CHECK(lower_left[2] > 2 * (lower_left[0] + lower_left[1]));
  // the background colour given
  const std::uint8_t* corner = pixel(im, 0, 0);
  CHECK(int(corner[0]) == 40);
  CHECK(int(corner[2]) == 48);
}

TEST_CASE("vertex_colour_picture: one colour per vertex, cameras_around needs a vertex") {
  const Picture m = sphere();
  const std::vector<dr::VertexColour> too_few(3, dr::VertexColour{1, 2, 3});
  const auto cam = dr::cameras_around(m.positions, 16)[0];
  CHECK_THROWS_AS(dr::vertex_colour_picture(m.positions, m.triangles, too_few, cam), std::invalid_argument);
  CHECK_THROWS_AS(dr::cameras_around({}, 16), std::invalid_argument);
}

TEST_CASE("vertex_colour_sheet: six views in two rows of four, then the colour bar from 0 at the bottom to 1 at the top") {
  const Picture p = sphere();
  const std::vector<dr::VertexColour> colours(p.positions.size() / 3, dr::VertexColour{0, 200, 0});
  const auto scale = [](float t) {
    return dr::VertexColour{std::uint8_t(255.0f * t + 0.5f), 0, std::uint8_t(255.0f * (1.0f - t) + 0.5f)};
  };
  const int size = 48, gap = 4;
  const difftrans::io::Image8 sheet = dr::vertex_colour_sheet(p.positions, p.triangles, colours, size, scale);
  CHECK(sheet.width == 4 * size + 5 * gap);
  CHECK(sheet.height == 2 * size + 3 * gap);
  REQUIRE(sheet.channels == 3);
  const auto at = [&](int x, int y) {
    const std::size_t i = 3 * (std::size_t(y) * std::size_t(sheet.width) + std::size_t(x));
    return dr::VertexColour{sheet.data[i], sheet.data[i + 1], sheet.data[i + 2]};
  };
  // the centre of each of the six views shows the sphere (green); the fourth
  // tile of the second row is empty (the background)
  for (int k = 0; k < 6; ++k) {
    const int r = k / 4, c = k % 4;
    const dr::VertexColour centre = at(gap + c * (size + gap) + size / 2, gap + r * (size + gap) + size / 2);
    CHECK(centre[1] > 60);
    CHECK(centre[0] == 0);
  }
  const dr::VertexColour empty = at(gap + 3 * (size + gap) + size / 2, gap + (size + gap) + size / 2);
  CHECK((empty[0] == empty[1] && empty[1] == empty[2]));
  // the bar in the third tile of the second row: blue (0) near its bottom, red (1) near its top
  const int bx = gap + 2 * (size + gap) + size / 2, top = gap + (size + gap);
  const dr::VertexColour low = at(bx, top + size - 9), high = at(bx, top + 8);
  CHECK(low[2] > 240);
  CHECK(low[0] < 15);
  CHECK(high[0] > 240);
  CHECK(high[2] < 15);
}
