// PNG through stb: sRGB in and out, masks (> 127 inside), decoding errors.
#include "difftrans/io/png.hpp"

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("PNG: a linear image written tone-mapped reads back to the same 8-bit levels") {
  TempDir dir;
  io::Image img(5, 3);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = io::srgb_to_linear(float((i * 37) % 256) / 255.0f);
  img.rgb[0] = 4.0f;   // clamped to 255
  img.rgb[1] = -1.0f;  // clamped to 0
  io::write_png(dir / "a.png", img);
  const io::Image8 raw = io::read_image8(dir / "a.png");
  CHECK(raw.width == 5);
  CHECK(raw.height == 3);
  CHECK(raw.channels == 3);
  CHECK(raw.data == io::tone_map(img));
  CHECK(raw.data[0] == 255);
  CHECK(raw.data[1] == 0);
  const io::Image back = io::read_png(dir / "a.png");
  CHECK(io::tone_map(back) == raw.data);
  CHECK(back.rgb[5] == doctest::Approx(img.rgb[5]).epsilon(1e-5));
}

TEST_CASE("PNG masks: > 127 is object; RGBA and grey files both read") {
  TempDir dir;
  io::Image8 grey{4, 1, 1, {0, 127, 128, 255}};
  io::write_png8(dir / "m.png", grey);
  const io::Mask m = io::read_mask(dir / "m.png");
  CHECK(m.inside == std::vector<std::uint8_t>{0, 0, 1, 1});
  io::Image8 rgba{2, 1, 4, {255, 255, 255, 255, 0, 0, 0, 255}};
  io::write_png8(dir / "rgba.png", rgba);
  CHECK(io::read_mask(dir / "rgba.png").inside == std::vector<std::uint8_t>{1, 0});
  CHECK(io::read_png(dir / "rgba.png").rgb[0] == doctest::Approx(1.0f));
  io::write_mask(dir / "w.png", m);
  CHECK(io::read_image8(dir / "w.png").data == std::vector<std::uint8_t>{0, 0, 255, 255});
}

TEST_CASE("PNG: missing, corrupt and unwritable files") {
  TempDir dir;
  CHECK(error_of([&] { io::read_png(dir / "none.png"); }) == (dir / "none.png").string() + ": file not found");
  write_text(dir / "junk.png", "this is not a png");
  CHECK(contains(error_of([&] { io::read_png(dir / "junk.png"); }), (dir / "junk.png").string() + ": cannot decode image"));
  io::Image nan(2, 2, std::nanf(""));
  CHECK(contains(error_of([&] { io::write_png(dir / "n.png", nan); }), "n.png: non-finite pixel value"));
  CHECK(error_of([&] { io::write_png(dir / "x/y.png", io::Image(1, 1)); }) == (dir / "x/y.png").string() + ": cannot write PNG");
}
