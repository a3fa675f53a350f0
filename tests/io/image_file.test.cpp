// read_image / write_image / image_size by extension.
#include "difftrans/io/image_file.hpp"

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("each format by extension: sizes from headers, values back") {
  TempDir dir;
  io::Image img(9, 4, 0.25f);
  img.set(8, 3, {1.0f, 0.0f, 0.5f});
  for (const char* name : {"a.png", "a.hdr", "a.exr", "B.EXR"}) {
    CAPTURE(name);
    io::write_image(dir / name, img);
    CHECK(io::image_size(dir / name) == difftrans::Vec2i(9, 4));
    const io::Image back = io::read_image(dir / name);
    CHECK(io::tone_map(back) == io::tone_map(img));
  }
  CHECK(error_of([&] { io::write_image(dir / "a.bmp", img); }) ==
        (dir / "a.bmp").string() + ": unsupported image format '.bmp' (expected .png, .hdr or .exr)");
  CHECK(error_of([&] { io::read_image(dir / "a.tiff"); }) ==
        (dir / "a.tiff").string() + ": unsupported image format '.tiff' (expected .png, .hdr or .exr)");
  write_text(dir / "bad.png", "nope");
  CHECK(contains(error_of([&] { io::image_size(dir / "bad.png"); }), "bad.png: cannot read image header"));
  CHECK(error_of([&] { io::image_size(dir / "gone.exr"); }) == (dir / "gone.exr").string() + ": file not found");
}
