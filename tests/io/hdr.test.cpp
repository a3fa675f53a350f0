// Radiance HDR through stb: linear values survive RGBE to its precision.
#include "difftrans/io/hdr.hpp"

#include <fstream>
#include <iterator>
#include <string>

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
  CHECK(contains(error_of([&] { io::read_hdr(dir / "xyze.hdr"); }), "xyze.hdr: unsupported FORMAT=32-bit_rle_xyze"));
  io::Image img(3, 2, 1.0f);
  img.set(1, 1, {1.0f, 1.0f, -INFINITY});
  CHECK(error_of([&] { io::write_hdr(dir / "b.hdr", img); }) ==
        (dir / "b.hdr").string() + ": non-finite pixel value -inf at (x 1, y 1) channel B");
}

TEST_CASE("HDR: truncated, corrupt and oversized RGBE files fail at once, naming the file") {
  TempDir dir;
  io::Image img(37, 5);  // width >= 8: written run-length encoded
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = 0.05f + float(i % 7) * 0.3f;
  io::write_hdr(dir / "full.hdr", img);
  std::ifstream in(dir / "full.hdr", std::ios::binary);
  const std::string whole((std::istreambuf_iterator<char>(in)), {});
  const std::size_t header = whole.find("+X 37\n") + 6;
  REQUIRE(header > 6);
  // every cut inside the pixels: an error, never a hang or a black map
  for (std::size_t cut = header; cut < whole.size(); ++cut) {
    write_text(dir / "cut.hdr", whole.substr(0, cut));
    const std::string e = error_of([&] { io::read_hdr(dir / "cut.hdr"); });
    CAPTURE(cut);
    CHECK(contains(e, "cut.hdr: "));
    CHECK((contains(e, "truncated") || contains(e, "holds only")));
  }
  CHECK(io::read_hdr(dir / "full.hdr").width == 37);
  // a header and no pixels; a size the file cannot hold (refused before any allocation)
  write_text(dir / "empty.hdr", whole.substr(0, header));
  CHECK(contains(error_of([&] { io::read_hdr(dir / "empty.hdr"); }), "holds only 0 bytes"));
  std::string huge = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 8000 +X 8000\n" + std::string(8192, '\x02');
  write_text(dir / "huge.hdr", huge);
  CHECK(contains(error_of([&] { io::read_hdr(dir / "huge.hdr"); }), "declares 8000 x 8000 pixels"));
  // a run of length 0 (the decoder would not advance) and a run past the scanline's end
  std::string bad = whole;
  bad[header + 4] = char(128);
  write_text(dir / "zero_run.hdr", bad);
  CHECK(contains(error_of([&] { io::read_hdr(dir / "zero_run.hdr"); }), "bad run-length data in scanline 0"));
  bad[header + 4] = char(128 + 100);
  write_text(dir / "long_run.hdr", bad);
  CHECK(contains(error_of([&] { io::read_hdr(dir / "long_run.hdr"); }), "bad run-length data in scanline 0"));
  // uncompressed pixels (width < 8) cut in half
  io::Image narrow(4, 6, 0.5f);
  io::write_hdr(dir / "narrow.hdr", narrow);
  std::ifstream in2(dir / "narrow.hdr", std::ios::binary);
  const std::string flat((std::istreambuf_iterator<char>(in2)), {});
  write_text(dir / "narrow_cut.hdr", flat.substr(0, flat.size() - 48));
  CHECK(contains(error_of([&] { io::read_hdr(dir / "narrow_cut.hdr"); }), "truncated"));
  CHECK(io::read_hdr(dir / "narrow.hdr").height == 6);
  // no FORMAT line, another orientation
  write_text(dir / "noformat.hdr", "#?RADIANCE\n\n-Y 1 +X 1\nabcd");
  CHECK(contains(error_of([&] { io::read_hdr(dir / "noformat.hdr"); }), "no FORMAT=32-bit_rle_rgbe"));
  write_text(dir / "flipped.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n+Y 1 +X 1\nabcd");
  CHECK(contains(error_of([&] { io::read_hdr(dir / "flipped.hdr"); }), "is not '-Y HEIGHT +X WIDTH'"));
}

TEST_CASE("HDR: the shipped maps cut at 10 %, 50 % and 99 % are refused") {
  const fs::path path = fs::path(DIFFTRANS_DATA_DIR) / "envmaps" / "venice_sunset_1k.hdr";
  REQUIRE(fs::exists(path));
  std::ifstream in(path, std::ios::binary);
  const std::string whole((std::istreambuf_iterator<char>(in)), {});
  TempDir dir;
  for (const double part : {0.1, 0.5, 0.99}) {
    CAPTURE(part);
    write_text(dir / "cut.hdr", whole.substr(0, std::size_t(part * double(whole.size()))));
    CHECK(contains(error_of([&] { io::read_hdr(dir / "cut.hdr"); }), "cut.hdr: truncated: the file ends inside"));
  }
}
