// OpenEXR: float RGB round trip, half and grey files, errors naming the file.
#include "difftrans/io/exr.hpp"

#include <ImfRgbaFile.h>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("EXR: float RGB round trip is exact") {
  TempDir dir;
  io::Image img(6, 5);
  for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float(i) * 0.123456789f - 2.0f;
  io::write_exr(dir / "a.exr", img);
  const io::Image back = io::read_exr(dir / "a.exr");
  CHECK(back.width == 6);
  CHECK(back.height == 5);
  CHECK(back.rgb == img.rgb);
}

TEST_CASE("EXR: half RGBA and luminance-only files") {
  TempDir dir;
  {
    Imf::Rgba pixels[2] = {Imf::Rgba(0.5f, 1.0f, 2.0f, 1.0f), Imf::Rgba(0.25f, 0.0f, 8.0f, 1.0f)};
    Imf::RgbaOutputFile file((dir / "h.exr").string().c_str(), 2, 1, Imf::WRITE_RGBA);
    file.setFrameBuffer(pixels, 1, 2);
    file.writePixels(1);
  }
  CHECK(io::read_exr(dir / "h.exr").rgb == std::vector<float>{0.5f, 1.0f, 2.0f, 0.25f, 0.0f, 8.0f});
  {
    Imf::Rgba pixels[2] = {Imf::Rgba(0.5f, 0.5f, 0.5f), Imf::Rgba(3.0f, 3.0f, 3.0f)};
    Imf::RgbaOutputFile file((dir / "y.exr").string().c_str(), 2, 1, Imf::WRITE_Y);
    file.setFrameBuffer(pixels, 1, 2);
    file.writePixels(1);
  }
  const io::Image grey = io::read_exr(dir / "y.exr");
  CHECK(grey.rgb[0] == doctest::Approx(grey.rgb[2]));
  CHECK(grey.rgb[3] == doctest::Approx(grey.rgb[5]));
  CHECK(grey.rgb[3] > grey.rgb[0]);
}

TEST_CASE("EXR: NaN pixels, corrupt and missing files") {
  TempDir dir;
  io::Image img(3, 3, 1.0f);
  img.rgb[4 * 3] = std::nanf("");
  CHECK(error_of([&] { io::write_exr(dir / "n.exr", img); }) ==
        (dir / "n.exr").string() + ": non-finite pixel value nan at (x 1, y 1) channel R");
  {  // written through OpenEXR directly, so that the reader meets the NaN
    Imf::Rgba pixels[2] = {Imf::Rgba(0.5f, 1.0f, 2.0f), Imf::Rgba(0.25f, std::nanf(""), 8.0f)};
    Imf::RgbaOutputFile file((dir / "n.exr").string().c_str(), 2, 1, Imf::WRITE_RGB);
    file.setFrameBuffer(pixels, 1, 2);
    file.writePixels(1);
  }
  CHECK(error_of([&] { io::read_exr(dir / "n.exr"); }) ==
        (dir / "n.exr").string() + ": non-finite pixel value nan at (x 1, y 0) channel G");
  write_text(dir / "junk.exr", "not an exr file at all");
  CHECK(contains(error_of([&] { io::read_exr(dir / "junk.exr"); }), (dir / "junk.exr").string() + ": cannot read EXR"));
  CHECK(error_of([&] { io::read_exr(dir / "none.exr"); }) == (dir / "none.exr").string() + ": file not found");
  CHECK(contains(error_of([&] { io::write_exr(dir / "no/dir.exr", io::Image(1, 1)); }), "cannot write EXR"));
}
