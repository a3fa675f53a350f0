// Scene directories: transforms_*.json with masks, scene.json, gt/, COLMAP
// fallback; cameras-only loading; every kind of bad input; write and reload.
#include "difftrans/io/dataset.hpp"

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
using difftrans::Vec3d;

namespace {

std::string identity_at(double z) {
  return "[[1,0,0,0],[0,1,0,0],[0,0,1," + std::to_string(z) + "],[0,0,0,1]]";
}

// A 8 x 6 scene: two training frames (one PNG named without extension, one
// EXR with a mask found by convention), one test frame, scene.json, gt/.
void write_scene(const fs::path& dir) {
  io::Image img(8, 6, 0.25f);
  io::write_image(in_new_dir(dir / "images/r_0.png"), img);
  io::write_image(in_new_dir(dir / "images/r_1.exr"), img);
  io::write_image(in_new_dir(dir / "images/t_0.hdr"), img);
  io::Mask mask(8, 6);
  mask.inside[10] = 1;
  io::write_mask(in_new_dir(dir / "masks/r_0.png"), mask);
  io::write_mask(in_new_dir(dir / "masks/r_1.png"), mask);
  write_text(dir / "transforms_train.json",
             std::string(R"({"camera_angle_x": 0.8, "w": 8, "h": 6, "frames": [)") +
                 R"({"file_path": "./images/r_0", "mask_path": "masks/r_0.png", "transform_matrix": )" + identity_at(3) +
                 R"(}, {"file_path": "images/r_1.exr", "transform_matrix": )" + identity_at(4) +
                 R"(}, {"file_path": "images/r_0.png", "environment_only": true, "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,5]]}]})");
  write_text(dir / "transforms_test.json",
             std::string(R"({"fl_x": 10, "fl_y": 12, "cx": 4.5, "w": 8, "h": 6, "frames": [)") +
                 R"({"file_path": "images/t_0", "transform_matrix": )" + identity_at(-3) + "}]}");
  write_text(dir / "scene.json", R"({"aabb": [[-1,-1,-1],[1,1,2]], "environment": "near"})");
  write_text(dir / "gt/mesh.obj", "v 0 0 0\n");
  write_text(dir / "gt/material.json", "{}");
}

}  // namespace

TEST_CASE("load a scene directory with pixels") {
  TempDir dir;
  write_scene(dir.path());
  const io::Scene s = io::load_scene(dir.path());
  REQUIRE(s.train.frames.size() == 3);
  const io::Frame& f0 = s.train.frames[0];
  CHECK(f0.name == "r_0");
  CHECK(f0.image_path == dir / "images/r_0.png");
  CHECK(f0.intrinsics.width == 8);
  CHECK(f0.intrinsics.fx == doctest::Approx(4.0 / std::tan(0.4)));
  CHECK(f0.intrinsics.cx == 4.0);
  CHECK(f0.position().z == doctest::Approx(3.0));
  CHECK(f0.image.width == 8);
  CHECK(f0.mask.count() == 1);
  CHECK(f0.mask.inside[10] == 1);
  CHECK(s.train.frames[1].mask_path == dir / "masks/r_1.png");  // by convention
  CHECK(s.train.frames[1].image.rgb[0] == doctest::Approx(0.25f));
  CHECK(s.train.frames[2].environment_only);
  CHECK(s.train.frames[2].position().z == doctest::Approx(5.0));  // 3 x 4 matrix
  REQUIRE(s.test.frames.size() == 1);
  const io::Intrinsics& k = s.test.frames[0].intrinsics;
  CHECK(k.fx == 10.0);
  CHECK(k.fy == 12.0);
  CHECK(k.cx == 4.5);
  CHECK(k.cy == 3.0);
  CHECK(s.test.frames[0].image_path == dir / "images/t_0.hdr");
  CHECK(contains(joined(s.warnings), "transforms_test.json: frames[0] (t_0) has no mask"));
  CHECK(s.has_scene_json);
  CHECK(s.settings.environment == io::EnvironmentKind::near);
  REQUIRE(s.settings.aabb);
  CHECK(s.settings.aabb->hi.z == 2.0);
  CHECK(s.gt.present);
  CHECK(s.gt.mesh == dir / "gt/mesh.obj");
  CHECK(s.gt.material == dir / "gt/material.json");
  CHECK(s.gt.envmap.empty());
  CHECK_FALSE(s.from_colmap);
}

TEST_CASE("cameras only: image files are not opened") {
  TempDir dir;
  write_scene(dir.path());
  write_text(dir / "images/r_1.exr", "corrupt");
  io::LoadOptions cameras;
  cameras.read_pixels = false;
  const io::Scene s = io::load_scene(dir.path(), cameras);
  CHECK(s.train.frames.size() == 3);
  CHECK(s.train.frames[1].image.rgb.empty());
  CHECK(contains(error_of([&] { io::load_scene(dir.path()); }), (dir / "images/r_1.exr").string() + ": cannot read EXR"));
}

TEST_CASE("w and h may be absent (original NeRF-synthetic): taken from the image") {
  TempDir dir;
  io::write_image(in_new_dir(dir / "train/r_0.png"), io::Image(8, 6));
  write_text(dir / "transforms_train.json",
             std::string(R"({"camera_angle_x": 0.6911, "frames": [{"file_path": "./train/r_0", "transform_matrix": )") +
                 identity_at(4) + "}]}");
  io::LoadOptions cameras;
  cameras.read_pixels = false;
  const io::Split s = io::load_transforms(dir / "transforms_train.json", cameras);
  CHECK(s.frames[0].intrinsics.width == 8);
  CHECK(s.frames[0].intrinsics.height == 6);
}

TEST_CASE("bad scene input: each error names the file and what is wrong") {
  TempDir dir;
  write_scene(dir.path());
  const auto train = dir / "transforms_train.json";
  const std::string t = train.string();
  const auto with_frames = [&](const std::string& frames, const std::string& top = R"("camera_angle_x": 0.8, "w": 8, "h": 6)") {
    write_text(train, "{" + top + ", \"frames\": [" + frames + "]}");
    return error_of([&] { io::load_scene(dir.path()); });
  };
  const std::string m = identity_at(3);
  // malformed JSON, located
  write_text(train, "{\"frames\": [\n{\"file_path\": \"images/r_0\",\n \"transform_matrix\" [[1]]}]}");
  CHECK(contains(error_of([&] { io::load_scene(dir.path()); }), t + ":3: malformed JSON at column 21"));
  // structure
  CHECK(with_frames("") == t + ": frames: no frames");
  CHECK(with_frames(R"({"file_path": "images/r_0"})") == t + ": frames[0].transform_matrix: missing");
  CHECK(with_frames(R"({"file_path": "images/nope", "transform_matrix": )" + m + "}") ==
        t + ": frames[0].file_path: no image 'images/nope' (tried it as given and with .exr, .hdr, .png, .jpg) in " +
            dir.path().string());
  CHECK(with_frames(R"({"file_path": "images/r_0", "mask_path": "masks/zz", "transform_matrix": )" + m + "}") ==
        t + ": frames[0].mask_path: no mask 'masks/zz' in " + dir.path().string());
  CHECK(with_frames(R"({"file_path": "images/r_0", "transform_matrix": [[1,0,0],[0,1,0],[0,0,1],[0,0,0]]})") ==
        t + ": frames[0].transform_matrix: expected 4 rows of 4 numbers");
  CHECK(with_frames(R"({"file_path": "images/r_0", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,"x"],[0,0,0,1]]})") ==
        t + ": frames[0].transform_matrix[2][3]: expected a number, found \"x\"");
  CHECK(contains(with_frames(R"({"file_path": "images/r_0", "transform_matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]})"),
                 t + ": frames[0].transform_matrix: camera matrix is not rigid"));
  CHECK(contains(with_frames(R"({"file_path": "images/r_0", "transform_matrix": [[1e999,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]})"),
                 t + ": malformed JSON"));  // JSON has no NaN/Inf: an overflowing number is the way in
  CHECK(with_frames(R"({"file_path": "images/r_0", "transform_matrix": )" + m + "}", R"("w": 8, "h": 6)") ==
        t + ": camera_angle_x: missing (give camera_angle_x or fl_x)");
  CHECK(with_frames(R"({"file_path": "images/r_0", "transform_matrix": )" + m + "}", R"("camera_angle_x": 4, "w": 8, "h": 6)") ==
        t + ": camera_angle_x: must lie in (0, pi) radians");
  CHECK(with_frames(R"({"file_path": "images/r_0", "transform_matrix": )" + m + "}", R"("camera_angle_x": 0.8, "w": 8)") ==
        t + ": h: missing (w and h go together)");
  CHECK(with_frames(R"({"file_path": "images/r_0", "fl_x": -3, "transform_matrix": )" + m + "}") ==
        t + ": frames[0]: focal length is not a positive finite number");
  // sizes: image against w, h; mask against image
  CHECK(with_frames(R"({"file_path": "images/r_0", "transform_matrix": )" + m + "}", R"("camera_angle_x": 0.8, "w": 16, "h": 6)") ==
        (dir / "images/r_0.png").string() + ": image is 8 x 6 but " + t + " declares 16 x 6");
  io::write_mask(in_new_dir(dir / "masks/big.png"), io::Mask(9, 6));
  CHECK(with_frames(R"({"file_path": "images/r_0", "mask_path": "masks/big.png", "transform_matrix": )" + m + "}") ==
        (dir / "masks/big.png").string() + ": mask is 9 x 6 but its image " + (dir / "images/r_0.png").string() + " is 8 x 6");
  // scene.json
  write_text(train, std::string(R"({"camera_angle_x": 0.8, "frames": [{"file_path": "images/r_0", "transform_matrix": )") + m + "}]}");
  write_text(dir / "scene.json", R"({"environment": "far"})");
  CHECK(error_of([&] { io::load_scene(dir.path()); }) ==
        (dir / "scene.json").string() + ": environment: 'far' is neither \"distant\" nor \"near\"");
  write_text(dir / "scene.json", R"({"aabb": [[0,0,0],[1,-1,1]]})");
  CHECK(error_of([&] { io::load_scene(dir.path()); }) ==
        (dir / "scene.json").string() + ": aabb: the first corner must be below the second on every axis");
  // missing pieces
  fs::remove(train);
  CHECK(error_of([&] { io::load_scene(dir.path()); }) ==
        t + ": file not found (and no COLMAP cameras.txt + images.txt in the scene directory)");
  CHECK(error_of([&] { io::load_scene(dir / "absent"); }) == (dir / "absent").string() + ": scene directory not found");
}

TEST_CASE("skip_bad_frames: bad frames become warnings, the rest load") {
  TempDir dir;
  write_scene(dir.path());
  const auto train = dir / "transforms_train.json";
  write_text(train, std::string(R"({"camera_angle_x": 0.8, "w": 8, "h": 6, "frames": [)") +
                        R"({"file_path": "images/r_0", "transform_matrix": )" + identity_at(3) + "}," +
                        R"({"file_path": "images/r_0", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,0,0],[0,0,0,1]]},)" +
                        R"({"file_path": "images/missing", "transform_matrix": )" + identity_at(3) + "}]}");
  io::LoadOptions options;
  options.skip_bad_frames = true;
  const io::Scene s = io::load_scene(dir.path(), options);
  CHECK(s.train.frames.size() == 1);
  const auto w = joined(s.warnings);
  CHECK(contains(w, "skipped a frame: " + train.string() + ": frames[1].transform_matrix: camera matrix is not rigid"));
  CHECK(contains(w, "skipped a frame: " + train.string() + ": frames[2].file_path: no image 'images/missing'"));
}

TEST_CASE("COLMAP fallback when there is no transforms_train.json") {
  TempDir dir;
  write_text(dir / "sparse/0/cameras.txt", "1 SIMPLE_PINHOLE 8 6 10 4 3\n");
  write_text(dir / "sparse/0/images.txt", "1 1 0 0 0 0 0 3 1 v.png\n\n");
  io::write_image(in_new_dir(dir / "images/v.png"), io::Image(8, 6));
  const io::Scene s = io::load_scene(dir.path());
  CHECK(s.from_colmap);
  REQUIRE(s.train.frames.size() == 1);
  CHECK(s.train.frames[0].position().z == doctest::Approx(-3.0));
  CHECK(s.test.frames.empty());
}

TEST_CASE("write_transforms and write_scene_settings, then load again") {
  TempDir dir;
  write_scene(dir.path());
  const io::Scene s = io::load_scene(dir.path());
  TempDir out;
  fs::copy(dir / "images", out / "images");
  fs::copy(dir / "masks", out / "masks");
  io::Split split = s.train;
  split.frames[1].intrinsics.fx *= 2.0;  // different intrinsics per frame are written per frame
  io::write_transforms(out / "transforms_train.json", split);
  io::write_transforms(out / "transforms_test.json", s.test);
  io::write_scene_settings(out / "scene.json", s.settings);
  const io::Scene back = io::load_scene(out.path());
  REQUIRE(back.train.frames.size() == split.frames.size());
  for (size_t i = 0; i < split.frames.size(); ++i) {
    const auto& a = split.frames[i];
    const auto& b = back.train.frames[i];
    CHECK(b.name == a.name);
    CHECK(b.image_path.filename() == a.image_path.filename());
    CHECK(b.mask_path.filename() == a.mask_path.filename());
    CHECK(b.environment_only == a.environment_only);
    CHECK(b.intrinsics.fx == doctest::Approx(a.intrinsics.fx));
    CHECK(b.camera_to_world == a.camera_to_world);
  }
  CHECK(back.test.frames[0].intrinsics.fy == 12.0);
  CHECK(back.settings.environment == io::EnvironmentKind::near);
  CHECK(back.settings.aabb->lo.x == -1.0);
}
