// COLMAP text models: conversion to camera-to-world OpenGL axes against
// closed forms and GLM's quaternions; errors located by line.
#include "difftrans/io/colmap.hpp"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
using difftrans::Vec3d;
using Mat4d = difftrans::Mat4<double>;

namespace {

void check_close(const Vec3d& a, const Vec3d& b, double eps = 1e-9) {
  CHECK(a.x == doctest::Approx(b.x).epsilon(eps));
  CHECK(a.y == doctest::Approx(b.y).epsilon(eps));
  CHECK(a.z == doctest::Approx(b.z).epsilon(eps));
}

const char* cameras_txt =
    "# Camera list with one line of data per camera:\n"
    "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
    "1 PINHOLE 8 6 10 11 4 3\n"
    "2 SIMPLE_RADIAL 8 6 9 4.5 3.5 0.01\n";

}  // namespace

TEST_CASE("identity pose: camera at the origin looking down +z with y down (OpenCV)") {
  const Mat4d m = io::colmap_to_camera_to_world({1, 0, 0, 0}, {0, 0, 0});
  io::Frame f;
  f.camera_to_world = m;
  check_close(f.position(), {0, 0, 0});
  check_close(f.forward(), {0, 0, 1});
  check_close(f.up(), {0, -1, 0});
}

TEST_CASE("camera looking at the origin: pose round trip through COLMAP's convention") {
  // OpenGL camera-to-world from lookAt; COLMAP stores R, t of world-to-camera in OpenCV axes.
  const Vec3d eye(2.0, 1.5, -3.0);
  const Mat4d c2w_gl = glm::inverse(glm::lookAt(eye, Vec3d(0.0), Vec3d(0, 1, 0)));
  const Mat4d c2w_cv = c2w_gl * Mat4d(glm::dvec4(1, 0, 0, 0), glm::dvec4(0, -1, 0, 0), glm::dvec4(0, 0, -1, 0),
                                      glm::dvec4(0, 0, 0, 1));
  const Mat4d w2c = glm::inverse(c2w_cv);
  const glm::dquat q = glm::quat_cast(difftrans::Mat3<double>(w2c));
  const Vec3d t(w2c[3]);
  const Mat4d m = io::colmap_to_camera_to_world({q.w, q.x, q.y, q.z}, t);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) CHECK(m[c][r] == doctest::Approx(c2w_gl[c][r]).epsilon(1e-9));
  io::Frame f;
  f.camera_to_world = m;
  check_close(f.position(), eye);
  check_close(f.forward(), -glm::normalize(eye));
}

TEST_CASE("load a COLMAP model with images and masks") {
  TempDir dir;
  write_text(dir / "sparse/cameras.txt", cameras_txt);
  write_text(dir / "sparse/images.txt",
             "# Image list with two lines of data per image:\n"
             "1 1 0 0 0 0 0 2 1 a.png\n"
             "\n"  // empty POINTS2D line
             "2 0.7071067811865476 0 0.7071067811865476 0 1 2 3 2 b c.png\n"
             "10 20 1 30 40 -1\n");
  io::write_image(in_new_dir(dir / "images/a.png"), io::Image(8, 6, 0.2f));
  io::write_image(in_new_dir(dir / "images/b c.png"), io::Image(8, 6, 0.4f));
  io::write_mask(in_new_dir(dir / "masks/a.png"), io::Mask(8, 6, true));
  std::vector<std::string> warnings;
  const io::Split s = io::load_colmap(dir / "sparse", dir / "images", dir / "masks", {}, &warnings);
  REQUIRE(s.frames.size() == 2);
  CHECK(s.frames[0].name == "a");
  CHECK(s.frames[0].intrinsics.fx == 10.0);
  CHECK(s.frames[0].intrinsics.fy == 11.0);
  CHECK(s.frames[0].intrinsics.cx == 4.0);
  CHECK(s.frames[0].mask.count() == 48);
  check_close(s.frames[0].position(), {0, 0, -2});  // C = -R^T t with R = I
  CHECK(s.frames[1].name == "b c");
  CHECK(s.frames[1].intrinsics.fx == 9.0);
  CHECK(s.frames[1].intrinsics.fy == 9.0);
  CHECK(s.frames[1].mask_path.empty());
  CHECK(s.frames[1].image.width == 8);
  // R = rotation by 90 degrees about y: C = -R^T (1, 2, 3) = (3, -2, -1)
  check_close(s.frames[1].position(), {3, -2, -1}, 1e-6);
  const auto w = joined(warnings);
  CHECK(contains(w, "cameras.txt:4: camera 2 has lens distortion, which is ignored"));
  CHECK(contains(w, "image 2 (b c.png) has no mask"));
}

TEST_CASE("COLMAP: bad input is an Error with file and line") {
  TempDir dir;
  io::write_image(in_new_dir(dir / "images/a.png"), io::Image(8, 6));
  const auto cams = dir / "m/cameras.txt";
  const auto imgs = dir / "m/images.txt";
  const auto load = [&](const std::string& cameras, const std::string& images) {
    write_text(cams, cameras);
    write_text(imgs, images);
    return error_of([&] { io::load_colmap(dir / "m", dir / "images"); });
  };
  const std::string good_image = "1 1 0 0 0 0 0 0 1 a.png\n\n";
  CHECK(load("1 OPENCV_FISHEYE 8 6 1 1 4 3 0 0 0 0\n", good_image) ==
        cams.string() + ":1: camera model 'OPENCV_FISHEYE' is not supported (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, "
                        "RADIAL, OPENCV, FULL_OPENCV)");
  CHECK(load("# c\n1 PINHOLE 8 6 10 10 4\n", good_image) == cams.string() + ":2: camera model PINHOLE takes 4 parameters, found 3");
  CHECK(load("1 PINHOLE 8 6 nan 10 4 3\n", good_image) == cams.string() + ":1: parameter 'nan' is not finite");
  CHECK(load("1 PINHOLE 8 6 -10 10 4 3\n", good_image) == cams.string() + ":1: camera 1: focal length is not a positive finite number");
  CHECK(load("1 PINHOLE 8 6 10 10 4 3\n1 PINHOLE 8 6 10 10 4 3\n", good_image) == cams.string() + ":2: camera id 1 appears twice");
  CHECK(load("", good_image) == cams.string() + ": no cameras");
  const std::string cam = "1 PINHOLE 8 6 10 10 4 3\n";
  CHECK(load(cam, "1 1 0 0 0 0 0 0 7 a.png\n\n") == imgs.string() + ":1: camera id 7 is not in cameras.txt");
  CHECK(load(cam, "1 2 0 0 0 0 0 0 1 a.png\n\n") == imgs.string() + ":1: rotation quaternion has norm 2.000000, expected 1");
  CHECK(load(cam, "1 1 0 0 0 inf 0 0 1 a.png\n\n") == imgs.string() + ":1: translation 'inf' is not finite");
  CHECK(load(cam, "1 1 0 0 0\n\n") == imgs.string() + ":1: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
  CHECK(load(cam, good_image + "2 1 0 0 0 0 0 0 1 gone.png\n\n") ==
        imgs.string() + ":3: image 2: file " + (dir / "images/gone.png").string() + " not found");
  CHECK(load("1 PINHOLE 4 6 10 10 2 3\n", good_image) ==
        (dir / "images/a.png").string() + ": image is 8 x 6 but " + cams.string() + " declares 4 x 6");
  CHECK(error_of([&] { io::load_colmap(dir / "nowhere", dir / "images"); }) ==
        (dir / "nowhere/cameras.txt").string() + ": file not found");
}
