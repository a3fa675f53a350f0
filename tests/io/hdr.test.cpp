// Radiance HDR through stb: linear values survive RGBE to its precision.
#include "difftrans/io/hdr.hpp"

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("HDR: write then read within RGBE precision (8-bit mantissa per pixel)") {
  TempDir dir;
  io::Image img(7, 4);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = 0.01f + 3.0f * float(i) / float(img.rgb.size());
  io::write_hdr(dir / "a.hdr", img);
  const io::Image back = io::read_hdr(dir / "a.hdr");
  REQUIRE(back.width == 7);
  REQUIRE(back.height == 4);
  for (size_t p = 0; p < img.pixel_count(); ++p) {
    const float peak = std::max(img.rgb[p * 3], std::max(img.rgb[p * 3 + 1], img.rgb[p * 3 + 2]));
    for (int c = 0; c < 3; ++c) CHECK(std::abs(back.rgb[p * 3 + size_t(c)] - img.rgb[p * 3 + size_t(c)]) <= peak / 128.0f);
  }
}

TEST_CASE("HDR: the shared environment maps read") {
  const fs::path path = fs::path(DIFFTRANS_DATA_DIR) / "envmaps" / "venice_sunset_1k.hdr";
  if (!fs::exists(path)) return;
  const io::Image env = io::read_hdr(path);
  CHECK(env.width == 1024);
  CHECK(env.height == 512);
}

TEST_CASE("HDR: wrong format, missing file, non-finite pixels") {
  TempDir dir;
  write_text(dir / "fake.hdr", "P3\n1 1\n255\n0 0 0\n");
  CHECK(error_of([&] { io::read_hdr(dir / "fake.hdr"); }) == (dir / "fake.hdr").string() + ": not a Radiance HDR file");
  CHECK(error_of([&] { io::read_hdr(dir / "none.hdr"); }) == (dir / "none.hdr").string() + ": file not found");
  write_text(dir / "xyze.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 4 +X 4\n");
  CHECK(contains(error_of([&] { io::read_hdr(dir / "xyze.hdr"); }), "xyze.hdr: cannot decode HDR image"));
  io::Image img(3, 2, 1.0f);
  img.set(1, 1, {1.0f, 1.0f, -INFINITY});
  CHECK(error_of([&] { io::write_hdr(dir / "b.hdr", img); }) ==
        (dir / "b.hdr").string() + ": non-finite pixel value -inf at (x 1, y 1) channel B");
}
