// sRGB curve, the tone mapping of docs/conventions.md and the image checks.
#include "difftrans/io/image.hpp"

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("sRGB curve: known points, continuity at the knee, inverse") {
  CHECK(io::linear_to_srgb(0.0f) == 0.0f);
  CHECK(io::linear_to_srgb(1.0f) == doctest::Approx(1.0f).epsilon(1e-6));
  CHECK(io::linear_to_srgb(0.0031308f) == doctest::Approx(0.04045f).epsilon(1e-4));
  CHECK(io::linear_to_srgb(0.0031309f) == doctest::Approx(0.04045f).epsilon(1e-4));
  CHECK(io::linear_to_srgb(0.5f) == doctest::Approx(0.735357f).epsilon(1e-5));  // 1.055 * 0.5^(1/2.4) - 0.055
  CHECK(io::srgb_to_linear(0.5f) == doctest::Approx(0.214041f).epsilon(1e-5));  // ((0.5 + 0.055) / 1.055)^2.4
  for (float x = 0.0f; x <= 1.0f; x += 0.01f) CHECK(io::srgb_to_linear(io::linear_to_srgb(x)) == doctest::Approx(x).epsilon(1e-5));
}

TEST_CASE("tone mapping: clamp, curve, round; every 8-bit level round-trips") {
  CHECK(io::tone_map_value(-1.0f) == 0);
  CHECK(io::tone_map_value(std::nanf("")) == 0);
  CHECK(io::tone_map_value(1.0f) == 255);
  CHECK(io::tone_map_value(37.0f) == 255);
  CHECK(io::tone_map_value(0.5f) == 188);  // round(255 * 0.735357) = round(187.52)
  CHECK(io::tone_map_value(0.002f) == 7);  // round(255 * 12.92 * 0.002) = round(6.59)
  for (int v = 0; v < 256; ++v) {
    CAPTURE(v);
    CHECK(io::tone_map_value(io::srgb_to_linear(float(v) / 255.0f)) == v);
  }
  const std::uint8_t grey[4] = {0, 128, 255, 7};
  const io::Image from_grey = io::from_srgb8(grey, 2, 2, 1);
  CHECK(io::tone_map(from_grey) == std::vector<std::uint8_t>{0, 0, 0, 128, 128, 128, 255, 255, 255, 7, 7, 7});
}

TEST_CASE("check_finite names the file and the first bad pixel") {
  io::Image img(4, 3, 0.5f);
  CHECK_NOTHROW(io::check_finite(img, "x.exr"));
  img.set(2, 1, {0.0f, INFINITY, std::nanf("")});
  CHECK(error_of([&] { io::check_finite(img, "x.exr"); }) == "x.exr: non-finite pixel value inf at (x 2, y 1) channel G");
  CHECK(img.at(2, 1).x == 0.0f);
  io::Image empty;
  CHECK(contains(error_of([&] { io::check_shape(empty, "e.png"); }), "e.png: image has no pixels"));
  io::Mask mask(3, 2);
  mask.inside[4] = 1;
  CHECK(mask.count() == 1);
  CHECK(mask.at(1, 1));
}

TEST_CASE("mask dilation and erosion by a Euclidean disk") {
  io::Mask m(9, 9);
  for (int y = 3; y <= 5; ++y)
    for (int x = 3; x <= 5; ++x) m.inside[size_t(y) * 9 + size_t(x)] = 1;  // a 3 x 3 square
  CHECK(io::morph_mask(m, 0).inside == m.inside);
  const io::Mask d1 = io::morph_mask(m, 1);
  CHECK(d1.count() == 9 + 4 * 3);  // the 4-neighbours of the square's edges, not its diagonal corners
  CHECK(d1.at(2, 4));
  CHECK_FALSE(d1.at(2, 2));
  const io::Mask d2 = io::morph_mask(m, 2);
  CHECK(d2.at(2, 2));  // distance sqrt(2) <= 2
  CHECK_FALSE(d2.at(1, 1));
  const io::Mask e1 = io::morph_mask(m, -1);
  CHECK(e1.count() == 1);
  CHECK(e1.at(4, 4));
  CHECK(io::morph_mask(m, -2).count() == 0);
  // pixels beyond the edge do not erode: a full mask stays full
  CHECK(io::morph_mask(io::Mask(5, 4, true), -2).count() == 20);
  // dilation then erosion of a square by 1 gives the square back
  CHECK(io::morph_mask(d1, -1).inside == m.inside);
}

TEST_CASE("mask blobs: pixels in a disc flipped once") {
  io::Mask m(20, 20);
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 10; ++x) m.inside[size_t(y) * 20 + size_t(x)] = 1;  // the left half inside
  // a disc of radius 3 centred on a pixel corner of the boundary: 32 pixel centres within it
  const io::Mask f = io::flip_discs(m, {{10.0f, 10.0f, 3.0f}});
  std::size_t changed = 0;
  for (std::size_t i = 0; i < m.inside.size(); ++i) changed += f.inside[i] != m.inside[i];
  CHECK(changed == 32);
  CHECK_FALSE(f.at(9, 9));  // inside the object, now out
  CHECK(f.at(10, 10));      // outside, now in
  CHECK(f.at(0, 0));        // far away: as it was
  CHECK(f.count() == m.count());  // the disc straddles the edge evenly
  // the same disc again flips back; two overlapping discs flip the overlap once
  CHECK(io::flip_discs(f, {{10.0f, 10.0f, 3.0f}}).inside == m.inside);
  const io::Mask twice = io::flip_discs(m, {{10.0f, 10.0f, 3.0f}, {10.0f, 10.0f, 3.0f}});
  CHECK(twice.inside == f.inside);
  CHECK(io::flip_discs(m, {}).inside == m.inside);
}
