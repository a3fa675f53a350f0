// Camera checks: rigid matrices, intrinsics, field of view; frame pixel checks.
#include "difftrans/io/frames.hpp"

#include <glm/gtc/matrix_transform.hpp>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
using Mat4d = difftrans::Mat4<double>;

TEST_CASE("rigid camera matrices pass; scale, shear, reflection, NaN and bad last rows fail") {
  Mat4d m = glm::rotate(Mat4d(1.0), 0.7, difftrans::Vec3d(0.3, 1.0, -0.2));
  m[3] = glm::dvec4(1.0, 2.0, 3.0, 1.0);
  CHECK_NOTHROW(io::check_camera_matrix(m, "t.json", "frames[0]"));
  Mat4d scaled = m;
  scaled[0] *= 1.001;  // |R^T R - I| ~ 2e-3
  CHECK(contains(error_of([&] { io::check_camera_matrix(scaled, "t.json", "frames[2].transform_matrix"); }),
                 "t.json: frames[2].transform_matrix: camera matrix is not rigid: its rotation part is not orthonormal"));
  Mat4d nearly = m;
  nearly[0] *= 1.00001;  // within 1e-4
  CHECK_NOTHROW(io::check_camera_matrix(nearly, "t.json", ""));
  Mat4d sheared = m;
  sheared[1] += 0.01 * sheared[0];
  CHECK(contains(error_of([&] { io::check_camera_matrix(sheared, "t.json", ""); }), "not orthonormal"));
  Mat4d mirrored = m;
  mirrored[2] = -mirrored[2];
  CHECK(contains(error_of([&] { io::check_camera_matrix(mirrored, "t.json", ""); }), "is a reflection"));
  Mat4d nan = m;
  nan[3][1] = std::nan("");
  CHECK(error_of([&] { io::check_camera_matrix(nan, "c.txt", "image 4", 9); }) ==
        "c.txt:9: image 4: camera matrix has a non-finite entry at row 1, column 3");
  Mat4d projective = m;
  projective[0][3] = 0.5;
  CHECK(contains(error_of([&] { io::check_camera_matrix(projective, "t.json", ""); }), "last row is not 0 0 0 1"));
}

TEST_CASE("camera positions farther than max_camera_distance from the origin are refused, with the value") {
  Mat4d m(1.0);
  m[3] = glm::dvec4(0.0, 0.0, 1e6, 1.0);  // at the limit
  CHECK_NOTHROW(io::check_camera_matrix(m, "t.json", "frames[0].transform_matrix"));
  m[3] = glm::dvec4(-3.0, 1e20, 2.0, 1.0);
  CHECK(error_of([&] { io::check_camera_matrix(m, "t.json", "frames[7].transform_matrix", 4); }) ==
        "t.json:4: frames[7].transform_matrix: camera position (-3, 1e+20, 2) lies beyond 1e+06 scene units from the "
        "origin: rays are traced in float, too coarse there to render an object near the origin, and the ray tracer "
        "refuses such origins; recentre or rescale the scene");
  m[3] = glm::dvec4(-1.5e6, 0.0, 0.0, 1.0);
  CHECK(contains(error_of([&] { io::check_camera_matrix(m, "c.txt", "image 2"); }), "c.txt: image 2: camera position (-1.5e+06, 0, 0)"));
}

TEST_CASE("intrinsics from the field of view; checks") {
  const auto k = io::Intrinsics::from_fov_y(256, 128, 40.0 * 3.14159265358979 / 180.0);
  CHECK(k.fy == doctest::Approx(64.0 / std::tan(20.0 * 3.14159265358979 / 180.0)));
  CHECK(k.fov_y() == doctest::Approx(40.0 * 3.14159265358979 / 180.0));
  CHECK(k.cx == 128.0);
  CHECK(k.cy == 64.0);
  const auto kx = io::Intrinsics::from_fov_x(100, 50, 1.0);
  CHECK(kx.fov_x() == doctest::Approx(1.0));
  io::Intrinsics bad = k;
  bad.fx = -1.0;
  CHECK(contains(error_of([&] { io::check_intrinsics(bad, "t.json", "frames[1]"); }), "t.json: frames[1]: focal length"));
  bad = k;
  bad.width = 0;
  CHECK(contains(error_of([&] { io::check_intrinsics(bad, "t.json", ""); }), "image size 0 x 128 is not positive"));
  // sizes beyond the limits (a side, the pixel count) fail before anything is allocated
  bad = k;
  bad.width = 100000;
  CHECK(error_of([&] { io::check_intrinsics(bad, "t.json", "frames[3]"); }) ==
        "t.json: frames[3]: image size 100000 x 128 exceeds the limit of 16384 pixels a side and 64 Mpx in all");
  bad = k;
  bad.width = bad.height = 16384;  // each side at the limit, 256 Mpx
  CHECK(contains(error_of([&] { io::check_intrinsics(bad, "t.json", ""); }), "image size 16384 x 16384 exceeds the limit"));
  bad.height = 4096;  // 64 Mpx: the largest accepted
  CHECK_NOTHROW(io::check_intrinsics(bad, "t.json", ""));
}

TEST_CASE("frame pixels: the image must match the intrinsics, the mask the image") {
  TempDir dir;
  io::write_image(dir / "a.exr", io::Image(8, 6, 0.5f));
  io::write_mask(dir / "m.png", io::Mask(8, 6, true));
  io::write_mask(dir / "small.png", io::Mask(4, 6, true));
  io::Frame f;
  f.image_path = dir / "a.exr";
  f.mask_path = dir / "m.png";
  f.intrinsics = io::Intrinsics::from_fov_x(8, 6, 1.0);
  io::read_frame_pixels(f, "t.json");
  CHECK(f.image.width == 8);
  CHECK(f.mask.count() == 48);
  f.mask_path = dir / "small.png";
  CHECK(error_of([&] { io::read_frame_pixels(f, "t.json"); }) ==
        (dir / "small.png").string() + ": mask is 4 x 6 but its image " + (dir / "a.exr").string() + " is 8 x 6");
  f.intrinsics.width = 16;
  CHECK(error_of([&] { io::read_frame_pixels(f, "t.json"); }) ==
        (dir / "a.exr").string() + ": image is 8 x 6 but t.json declares 16 x 6");
}

TEST_CASE("cameras only: the declared size is checked against the image and mask headers") {
  TempDir dir;
  io::write_image(dir / "a.png", io::Image(64, 64, 0.5f));
  io::write_mask(dir / "m.png", io::Mask(64, 64, true));
  io::write_mask(dir / "other.png", io::Mask(32, 64, true));
  io::Frame f;
  f.image_path = dir / "a.png";
  f.mask_path = dir / "m.png";
  f.intrinsics = io::Intrinsics::from_fov_x(64, 64, 1.0);
  CHECK_NOTHROW(io::check_frame_headers(f, "t.json"));
  CHECK(f.image.rgb.empty());  // no pixels read
  f.intrinsics = io::Intrinsics::from_fov_x(4096, 4096, 1.0);
  CHECK(error_of([&] { io::check_frame_headers(f, "t.json"); }) ==
        (dir / "a.png").string() + ": image is 64 x 64 but t.json declares 4096 x 4096");
  f.intrinsics = io::Intrinsics::from_fov_x(64, 64, 1.0);
  f.mask_path = dir / "other.png";
  CHECK(error_of([&] { io::check_frame_headers(f, "t.json"); }) ==
        (dir / "other.png").string() + ": mask is 32 x 64 but its image " + (dir / "a.png").string() + " is 64 x 64");
  write_text(dir / "broken.png", "not a png");
  f.image_path = dir / "broken.png";
  CHECK(contains(error_of([&] { io::check_frame_headers(f, "t.json"); }), (dir / "broken.png").string() + ": cannot read image header"));
}

TEST_CASE("frame pixels: a mask with no object pixel is warned about (not in environment-only frames)") {
  TempDir dir;
  io::write_image(dir / "a.exr", io::Image(8, 6, 0.5f));
  io::write_mask(dir / "empty.png", io::Mask(8, 6, false));
  io::Frame f;
  f.name = "a";
  f.image_path = dir / "a.exr";
  f.mask_path = dir / "empty.png";
  f.intrinsics = io::Intrinsics::from_fov_x(8, 6, 1.0);
  std::vector<std::string> warnings;
  io::read_frame_pixels(f, "t.json", {}, &warnings);
  REQUIRE(warnings.size() == 1);
  CHECK(warnings[0] == (dir / "empty.png").string() +
                           ": the mask of frame a has no foreground pixel (the object is nowhere in this view)");
  CHECK_FALSE(io::has_foreground(f.mask));
  warnings.clear();
  f.environment_only = true;
  io::read_frame_pixels(f, "t.json", {}, &warnings);
  CHECK(warnings.empty());
  io::Mask one(8, 6);
  one.inside[47] = 1;
  CHECK(io::has_foreground(one));
}
