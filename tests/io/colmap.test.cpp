// COLMAP models, text and binary: conversion to camera-to-world OpenGL axes
// against closed forms and GLM's quaternions and back; binary round trips
// through the writers; distortion refused; truncated and corrupt files give
// errors located by line or byte.
#include "difftrans/io/colmap.hpp"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <vector>

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
    "2 SIMPLE_RADIAL 8 6 9 4.5 3.5 0\n";  // zero distortion: a pinhole camera

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
  CHECK(contains(w, "images.txt:4: image 2 (b c.png) has no mask in " + (dir / "masks").string()));
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
        cams.string() + ":1: camera 1: camera model OPENCV_FISHEYE is a fisheye lens model, which is not a pinhole "
                        "projection; difftrans needs pinhole images: undistort them first (colmap image_undistorter "
                        "writes undistorted images and a PINHOLE model)");
  CHECK(load("1 SIMPLE_RADIAL 8 6 9 4 3 0.01\n", good_image) ==
        cams.string() + ":1: camera 1: camera model SIMPLE_RADIAL has lens distortion (k = 0.01); "
                        "difftrans needs pinhole images: undistort them first (colmap image_undistorter writes "
                        "undistorted images and a PINHOLE model)");
  CHECK(contains(load("1 OPENCV 8 6 9 9 4 3 0 -0.2 0 0.001\n", good_image),
                 ":1: camera 1: camera model OPENCV has lens distortion (k2 = -0.2"));
  CHECK(contains(load("1 OPENCV 8 6 9 9 4 3 0 -0.2 0 0.001\n", good_image), ", p2 = 0.001"));
  CHECK(load("1 KANNALA 8 6 1 1 4 3\n", good_image) ==
        cams.string() + ":1: camera model 'KANNALA' is not a COLMAP model (" + io::colmap_model_names() + ")");
  CHECK(load("# c\n1 PINHOLE 8 6 10 10 4\n", good_image) ==
        cams.string() + ":2: camera 1: camera model PINHOLE takes 4 parameters, found 3");
  CHECK(load("1 PINHOLE 8.5 6 10 10 4 3\n", good_image) ==
        cams.string() + ":1: camera 1: image size 8.5 x 6 is not a positive integer size (at most 1000000)");
  CHECK(load("1 PINHOLE 8 6 nan 10 4 3\n", good_image) == cams.string() + ":1: parameter 'nan' is not finite");
  CHECK(load("1 PINHOLE 8 6 -10 10 4 3\n", good_image) == cams.string() + ":1: camera 1: focal length is not a positive finite number");
  CHECK(load("1 PINHOLE 8 6 10 10 4 3\n1 PINHOLE 8 6 10 10 4 3\n", good_image) == cams.string() + ":2: camera id 1 appears twice");
  CHECK(load("", good_image) == cams.string() + ": no cameras");
  const std::string cam = "1 PINHOLE 8 6 10 10 4 3\n";
  CHECK(load(cam, "1 1 0 0 0 0 0 0 7 a.png\n\n") == imgs.string() + ":1: image 1: camera id 7 is not in cameras.txt");
  CHECK(load(cam, "1 2 0 0 0 0 0 0 1 a.png\n\n") ==
        imgs.string() + ":1: image 1: rotation quaternion has norm 2.000000, expected 1");
  CHECK(load(cam, good_image + "1 1 0 0 0 0 0 0 1 a.png\n\n") == imgs.string() + ":3: image 1: image id appears twice");
  CHECK(load(cam, "1 1 0 0 0 inf 0 0 1 a.png\n\n") == imgs.string() + ":1: translation 'inf' is not finite");
  CHECK(load(cam, "1 1 0 0 0\n\n") == imgs.string() + ":1: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
  CHECK(load(cam, good_image + "2 1 0 0 0 0 0 0 1 gone.png\n\n") ==
        imgs.string() + ":3: image 2: file " + (dir / "images/gone.png").string() + " not found");
  CHECK(load("1 PINHOLE 4 6 10 10 2 3\n", good_image) ==
        (dir / "images/a.png").string() + ": image is 8 x 6 but " + cams.string() + " declares 4 x 6");
  CHECK(error_of([&] { io::load_colmap(dir / "nowhere", dir / "images"); }) ==
        (dir / "nowhere/cameras.txt").string() + ": file not found");
}

namespace {

// A random rotation (uniform quaternion) and a camera centre on a sphere of radius 3.
Mat4d random_camera(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  glm::dquat q(n(rng), n(rng), n(rng), n(rng));
  q = glm::normalize(q);
  Mat4d m(glm::mat3_cast(q));
  const Vec3d c = glm::normalize(Vec3d(n(rng), n(rng), n(rng))) * 3.0;
  m[3] = glm::dvec4(c, 1.0);
  return m;
}

// A binary model by hand: two cameras (SIMPLE_PINHOLE, OPENCV with zero
// distortion) and two images with 2D points, for the corruption tests.
struct BinaryModel {
  std::map<std::uint32_t, io::ColmapCamera> cameras;
  std::vector<io::ColmapImage> images;
};

BinaryModel small_model() {
  BinaryModel m;
  io::ColmapCamera a;
  a.model = "SIMPLE_PINHOLE";
  a.intrinsics.width = 8;
  a.intrinsics.height = 6;
  a.params = {10, 4, 3};
  io::ColmapCamera b = a;
  b.model = "OPENCV";
  b.params = {9, 11, 4.5, 3.5, 0, 0, 0, 0};
  m.cameras[3] = a;
  m.cameras[7] = b;
  io::ColmapImage i1;
  i1.id = 1;
  i1.camera_id = 3;
  i1.name = "a.png";
  i1.t = Vec3d(0, 0, 2);
  i1.points2d = {{1.5, 2.5, -1}, {3.0, 4.0, 12}};
  io::ColmapImage i2 = i1;
  i2.id = 2;
  i2.camera_id = 7;
  i2.name = "sub/b.png";
  i2.q_wxyz = glm::dvec4(0.7071067811865476, 0, 0.7071067811865476, 0);
  i2.t = Vec3d(1, 2, 3);
  i2.points2d = {{0.5, 0.5, 3}};
  m.images = {i1, i2};
  return m;
}

std::string file_bytes(const fs::path& p) { return difftrans::io::detail::read_file_text(p); }

void write_bytes(const fs::path& p, const std::string& bytes) {
  difftrans::io::detail::write_file_bytes(p, bytes.data(), bytes.size());
}

}  // namespace

TEST_CASE("camera_to_world_to_colmap inverts colmap_to_camera_to_world (every branch of the quaternion)") {
  std::mt19937_64 rng(5);
  std::vector<Mat4d> cameras;
  for (int i = 0; i < 200; ++i) cameras.push_back(random_camera(rng));
  // rotations by 180 degrees about each axis: the trace is -1, the other branches
  for (const Vec3d axis : {Vec3d(1, 0, 0), Vec3d(0, 1, 0), Vec3d(0, 0, 1)})
    cameras.push_back(glm::rotate(Mat4d(1.0), 3.14159265358979323846, axis));
  for (const Mat4d& m : cameras) {
    const io::ColmapPose p = io::camera_to_world_to_colmap(m);
    CHECK(p.q_wxyz.x >= 0.0);  // w
    CHECK(glm::length(p.q_wxyz) == doctest::Approx(1.0).epsilon(1e-12));
    const Mat4d back = io::colmap_to_camera_to_world(p.q_wxyz, p.t);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) CHECK(back[c][r] == doctest::Approx(m[c][r]).epsilon(1e-12).scale(1.0));
  }
}

TEST_CASE("binary model: write_colmap_binary, then load_colmap reads the same cameras, images and masks") {
  TempDir dir;
  std::mt19937_64 rng(11);
  io::Split split;
  for (int i = 0; i < 5; ++i) {
    io::Frame f;
    f.name = "v" + std::to_string(i);
    f.image_path = dir / ("images/" + f.name + ".png");
    f.intrinsics = i == 3 ? io::Intrinsics{8, 6, 7.5, 7.25, 4.25, 2.75} : io::Intrinsics::from_fov_y(8, 6, 0.7);
    f.camera_to_world = random_camera(rng);
    io::write_image(in_new_dir(f.image_path), io::Image(8, 6, 0.1f * float(i)));
    split.frames.push_back(f);
  }
  io::write_mask(in_new_dir(dir / "masks/v1.png"), io::Mask(8, 6, true));
  io::write_colmap_binary(dir / "sparse/0", split, dir / "images");
  CHECK(fs::file_size(dir / "sparse/0/points3D.bin") == 8);
  const auto cameras = io::read_colmap_cameras_binary(dir / "sparse/0/cameras.bin");
  CHECK(cameras.size() == 2);  // frame 3 has its own intrinsics
  CHECK(io::colmap_model_format(dir / "sparse/0") == "binary");
  std::vector<std::string> warnings;
  const io::Split back = io::load_colmap(dir / "sparse/0", dir / "images", dir / "masks", {}, &warnings);
  REQUIRE(back.frames.size() == split.frames.size());
  CHECK(back.file == dir / "sparse/0/images.bin");
  for (std::size_t i = 0; i < split.frames.size(); ++i) {
    const auto& a = split.frames[i];
    const auto& b = back.frames[i];
    CHECK(b.name == a.name);
    CHECK(b.image_path == a.image_path);
    CHECK(b.intrinsics.fx == a.intrinsics.fx);
    CHECK(b.intrinsics.fy == a.intrinsics.fy);
    CHECK(b.intrinsics.cx == a.intrinsics.cx);
    CHECK(b.intrinsics.cy == a.intrinsics.cy);
    CHECK(b.intrinsics.width == 8);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) CHECK(b.camera_to_world[c][r] == doctest::Approx(a.camera_to_world[c][r]).epsilon(1e-12).scale(1.0));
    CHECK(b.image.rgb[0] == doctest::Approx(io::read_image(a.image_path).rgb[0]));
  }
  CHECK(back.frames[1].mask.count() == 48);
  CHECK(contains(joined(warnings), "images.bin: byte "));
  CHECK(contains(joined(warnings), "(image 1) (v0.png) has no mask in " + (dir / "masks").string()));
}

TEST_CASE("binary model: several camera models, 2D points skipped, distortion-free models read as pinhole") {
  TempDir dir;
  const BinaryModel m = small_model();
  io::write_image(in_new_dir(dir / "images/a.png"), io::Image(8, 6));
  io::write_image(in_new_dir(dir / "images/sub/b.png"), io::Image(8, 6));
  io::write_colmap_cameras_binary(in_new_dir(dir / "m/cameras.bin"), m.cameras);
  io::write_colmap_images_binary(dir / "m/images.bin", m.images);
  // the documented layout, byte by byte: count, then id, model id, width, height, params
  const std::string cams = file_bytes(dir / "m/cameras.bin");
  CHECK(cams.size() == 8 + (4 + 4 + 8 + 8 + 3 * 8) + (4 + 4 + 8 + 8 + 8 * 8));
  CHECK(cams.substr(0, 8) == std::string("\x02\0\0\0\0\0\0\0", 8));
  CHECK(cams.substr(8, 8) == std::string("\x03\0\0\0\0\0\0\0", 8));  // id 3, SIMPLE_PINHOLE (0)
  CHECK(file_bytes(dir / "m/images.bin").size() == 8 + 2 * (4 + 56 + 4 + 8) + 6 + 10 + 3 * 24);
  const io::Split s = io::load_colmap(dir / "m", dir / "images");
  REQUIRE(s.frames.size() == 2);
  CHECK(s.frames[0].intrinsics.fx == 10.0);
  CHECK(s.frames[0].intrinsics.fy == 10.0);
  CHECK(s.frames[1].intrinsics.fy == 11.0);
  CHECK(s.frames[1].intrinsics.cx == 4.5);
  CHECK(s.frames[1].name == "b");
  check_close(s.frames[1].position(), {3, -2, -1}, 1e-6);
  check_close(s.frames[0].position(), {0, 0, -2});
}

TEST_CASE("binary model: lens distortion and fisheye models are refused, naming the model and the parameters") {
  TempDir dir;
  BinaryModel m = small_model();
  io::write_colmap_images_binary(dir / "images.bin", m.images);
  const auto cams = dir / "cameras.bin";
  const auto error = [&](const std::string& model, const std::vector<double>& params) {
    m.cameras[7].model = model;
    m.cameras[7].params = params;
    io::write_colmap_cameras_binary(cams, m.cameras);
    return error_of([&] { io::read_colmap_cameras_binary(cams); });
  };
  CHECK(error("OPENCV", {9, 9, 4, 3, 0.1, 0, 0, -0.002}) ==
        cams.string() + ": byte 56, camera record 2 of 2 (camera 7): camera model OPENCV has lens distortion (k1 = 0.1, "
                        "p2 = -0.002); difftrans needs pinhole images: undistort them first (colmap image_undistorter "
                        "writes undistorted images and a PINHOLE model)");
  CHECK(contains(error("FULL_OPENCV", {9, 9, 4, 3, 0, 0, 0, 0, 0, 0, 0, 1e-9}), "FULL_OPENCV has lens distortion (k6 = 1e-09)"));
  CHECK(contains(error("RADIAL_FISHEYE", {9, 4, 3, 0, 0}), "camera model RADIAL_FISHEYE is a fisheye lens model"));
  CHECK(contains(error("PINHOLE", {9, -9, 4, 3}), "camera 7): focal length is not a positive finite number"));
  CHECK(contains(error("PINHOLE", {9, std::nan(""), 4, 3}), "parameter fy = nan is not finite"));
  // FOV with omega = 0 is a pinhole camera
  m.cameras[7].model = "FOV";
  m.cameras[7].params = {9, 9, 4, 3, 0};
  io::write_colmap_cameras_binary(cams, m.cameras);
  CHECK(io::read_colmap_cameras_binary(cams).at(7).intrinsics.fx == 9.0);
}

TEST_CASE("binary model: every truncation and corrupt counts, ids, names and poses are errors at a byte offset") {
  TempDir dir;
  const BinaryModel m = small_model();
  const auto cams = dir / "cameras.bin";
  const auto imgs = dir / "images.bin";
  io::write_colmap_cameras_binary(cams, m.cameras);
  io::write_colmap_images_binary(imgs, m.images);
  const std::string good_cams = file_bytes(cams), good_imgs = file_bytes(imgs);
  // every proper prefix of either file is refused with the file's name and the byte where it ends
  for (std::size_t n = 0; n < good_cams.size(); ++n) {
    write_bytes(cams, good_cams.substr(0, n));
    const std::string e = error_of([&] { io::read_colmap_cameras_binary(cams); });
    CHECK(contains(e, cams.string() + ": byte "));
    CHECK((contains(e, "the file ends inside") || contains(e, "needs at least")));
  }
  for (std::size_t n = 0; n < good_imgs.size(); ++n) {
    write_bytes(imgs, good_imgs.substr(0, n));
    const std::string e = error_of([&] { io::read_colmap_images_binary(imgs); });
    CHECK(contains(e, imgs.string() + ": byte "));
    CHECK((contains(e, "the file ends inside") || contains(e, "needs")));
  }
  write_bytes(cams, good_cams.substr(0, 60));
  CHECK(error_of([&] { io::read_colmap_cameras_binary(cams); }) ==
        cams.string() + ": byte 0: camera count 2 needs at least 96 bytes, but only 52 follow");
  write_bytes(cams, good_cams.substr(0, 120));
  CHECK(error_of([&] { io::read_colmap_cameras_binary(cams); }) ==
        cams.string() + ": byte 80, camera record 2 of 2 (camera 7): the file ends inside the camera parameters (64 "
                        "bytes needed, 40 left of 120)");
  const auto patched = [](std::string bytes, std::size_t at, std::uint64_t value, int width) {
    for (int i = 0; i < width; ++i) bytes[at + std::size_t(i)] = char((value >> (8 * i)) & 0xff);
    return bytes;
  };
  const auto cams_error = [&](const std::string& bytes) {
    write_bytes(cams, bytes);
    return error_of([&] { io::read_colmap_cameras_binary(cams); });
  };
  const auto imgs_error = [&](const std::string& bytes) {
    write_bytes(imgs, bytes);
    return error_of([&] { io::read_colmap_images_binary(imgs); });
  };
  // a count larger than the file can hold is refused before anything is allocated
  CHECK(cams_error(patched(good_cams, 0, 1000000000000ull, 8)) ==
        cams.string() + ": byte 0: camera count 1000000000000 needs at least 48000000000000 bytes, but only 136 follow");
  CHECK(contains(imgs_error(patched(good_imgs, 0, ~0ull, 8)),
                 imgs.string() + ": byte 0: image count 18446744073709551615 needs at least more bytes, but only"));
  CHECK(cams_error(patched(good_cams, 12, 42, 4)) ==
        cams.string() + ": byte 12, camera record 1 of 2 (camera 3): camera model id 42 is not a COLMAP model (0 to 11: " +
            io::colmap_model_names() + ")");
  CHECK(cams_error(patched(good_cams, 16, 0, 8)) ==
        cams.string() + ": byte 16, camera record 1 of 2 (camera 3): image size 0 x 6 is not a positive size (at most 1000000)");
  CHECK(cams_error(patched(good_cams, 56, 3, 4)) ==
        cams.string() + ": byte 56, camera record 2 of 2 (camera 3): camera id 3 appears twice");
  CHECK(cams_error(good_cams + "xyz") ==
        cams.string() + ": byte 144: 3 bytes after the last camera record (the count at byte 0 says there are no more)");
  CHECK(cams_error(patched(good_cams, 0, 0, 8).substr(0, 8)) == cams.string() + ": no cameras");
  // images: the 2D point count of the first image (after id, pose, camera id and "a.png\0" at byte 8 + 4 + 56 + 4)
  const std::size_t points_at = 8 + 4 + 56 + 4 + 6;
  CHECK(imgs_error(patched(good_imgs, points_at, 5000000000ull, 8)) ==
        imgs.string() + ": byte 78, image record 1 of 2 (image 1, a.png): 2D point count 5000000000 needs 120000000000 "
                        "bytes, but only 154 follow");
  const std::string no_nul = patched(good_imgs, 0, 1, 8).substr(0, 8 + 4 + 56 + 4) + std::string(70, 'x');
  CHECK(imgs_error(no_nul) == imgs.string() + ": byte 72, image record 1 of 1 (image 1): the file ends inside the image "
                                              "name (no terminating NUL in the 70 bytes left)");
  CHECK(imgs_error(patched(good_imgs, 8 + 4 + 8, 0x7ff8000000000000ull, 8)) ==
        imgs.string() + ": byte 20, image record 1 of 2 (image 1, a.png): quaternion component nan is not finite");
  CHECK(imgs_error(good_imgs + std::string(1, '\0')) ==
        imgs.string() + ": byte 240: 1 bytes after the last image record (the count at byte 0 says there are no more)");
  // through load_colmap: a bad pose or an unknown camera names the image record
  io::write_colmap_cameras_binary(cams, m.cameras);
  std::vector<io::ColmapImage> bad = m.images;
  bad[1].camera_id = 9;
  io::write_colmap_images_binary(imgs, bad);
  io::write_image(in_new_dir(dir / "images/a.png"), io::Image(8, 6));
  CHECK(error_of([&] { io::load_colmap(dir.path(), dir / "images"); }) ==
        imgs.string() + ": byte 134, image record 2 of 2 (image 2): camera id 9 is not in cameras.bin");
  bad[1].camera_id = 7;
  bad[1].q_wxyz *= 2.0;
  io::write_colmap_images_binary(imgs, bad);
  CHECK(error_of([&] { io::load_colmap(dir.path(), dir / "images"); }) ==
        imgs.string() + ": byte 134, image record 2 of 2 (image 2): rotation quaternion has norm 2.000000, expected 1");
}
