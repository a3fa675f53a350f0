// Scene directories: transforms_*.json with masks, scene.json, gt/, COLMAP
// fallback (text, binary in sparse/0); masks from files, a folder, the alpha
// channel or a threshold; cameras-only loading; every kind of bad input;
// write and reload.
#include "difftrans/io/dataset.hpp"

#include <cstdint>
#include <string>
#include <vector>

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

TEST_CASE("cameras only, sizes unchecked: image files are not opened") {
  TempDir dir;
  write_scene(dir.path());
  write_text(dir / "images/r_1.exr", "corrupt");
  io::LoadOptions cameras;
  cameras.read_pixels = false;
  cameras.check_sizes = false;
  const io::Scene s = io::load_scene(dir.path(), cameras);
  CHECK(s.train.frames.size() == 3);
  CHECK(s.train.frames[1].image.rgb.empty());
  CHECK(contains(error_of([&] { io::load_scene(dir.path()); }), (dir / "images/r_1.exr").string() + ": cannot read EXR"));
}

TEST_CASE("cameras only: w and h are checked at load against the image headers and the size limits") {
  TempDir dir;
  write_scene(dir.path());
  const auto train = dir / "transforms_train.json";
  io::LoadOptions cameras;
  cameras.read_pixels = false;
  CHECK(io::load_scene(dir.path(), cameras).train.frames.size() == 3);
  const auto with_size = [&](int w, int h) {
    write_text(train, R"({"camera_angle_x": 0.8, "w": )" + std::to_string(w) + R"(, "h": )" + std::to_string(h) +
                          R"(, "frames": [{"file_path": "images/r_0", "transform_matrix": )" + identity_at(3) + "}]}");
    return error_of([&] { io::load_scene(dir.path(), cameras); });
  };
  // the image's header disagrees: refused before any rendering, naming the image and the file
  CHECK(with_size(4096, 4096) == (dir / "images/r_0.png").string() + ": image is 8 x 6 but " + train.string() +
                                     " declares 4096 x 4096");
  // beyond the limits: refused naming the file and the frame (no allocation attempted)
  CHECK(with_size(100000, 100000) == train.string() + ": frames[0]: image size 100000 x 100000 exceeds the limit of "
                                                      "16384 pixels a side and 64 Mpx in all");
  // the same with pixels
  CHECK(error_of([&] { io::load_scene(dir.path()); }) ==
        train.string() + ": frames[0]: image size 100000 x 100000 exceeds the limit of 16384 pixels a side and 64 Mpx in all");
  // a corrupt image is found at load too
  write_scene(dir.path());
  write_text(dir / "images/r_1.exr", "corrupt");
  CHECK(contains(error_of([&] { io::load_scene(dir.path(), cameras); }), (dir / "images/r_1.exr").string() + ": cannot read EXR header"));
}

TEST_CASE("a camera far from the origin is refused at load, naming the file, the frame and the position") {
  TempDir dir;
  write_scene(dir.path());
  const auto train = dir / "transforms_train.json";
  write_text(train, std::string(R"({"camera_angle_x": 0.8, "w": 8, "h": 6, "frames": [)") +
                        R"({"file_path": "images/r_0", "transform_matrix": )" + identity_at(3) + "}," +
                        R"({"file_path": "images/r_0", "transform_matrix": [[1,0,0,1e20],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]})");
  CHECK(contains(error_of([&] { io::load_scene(dir.path()); }),
                 train.string() + ": frames[1].transform_matrix: camera position (1e+20, 0, 3) lies beyond 1e+06 scene units"));
}

TEST_CASE("masks without a foreground pixel: each is a warning; all of them, an error at load") {
  TempDir dir;
  write_scene(dir.path());
  // r_1's mask empty: a warning, the scene loads
  io::write_mask(dir / "masks/r_1.png", io::Mask(8, 6));
  const io::Scene s = io::load_scene(dir.path());
  CHECK(contains(joined(s.warnings), (dir / "masks/r_1.png").string() + ": the mask of frame r_1 has no foreground pixel"));
  CHECK_FALSE(contains(joined(s.warnings), "masks/r_0.png"));
  // both empty (the third frame is environment-only and has no mask to count)
  io::write_mask(dir / "masks/r_0.png", io::Mask(8, 6));
  CHECK(error_of([&] { io::load_scene(dir.path()); }) ==
        (dir / "transforms_train.json").string() + ": no foreground pixel in any mask: the 2 masks of the training "
                                                   "views are all empty (the first: " + (dir / "masks/r_0.png").string() + ")");
  // masks from a threshold that nothing passes
  io::LoadOptions threshold;
  threshold.masks.source = io::MaskSource::threshold;
  threshold.masks.threshold = 0.99;
  CHECK(contains(error_of([&] { io::load_scene(dir.path(), threshold); }), "no foreground pixel in any mask"));
  // without masks there is nothing to check
  io::LoadOptions none;
  none.masks.source = io::MaskSource::none;
  CHECK(io::load_scene(dir.path(), none).train.frames.size() == 3);
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
        t + ": file not found (and no COLMAP model, cameras.bin + images.bin or cameras.txt + images.txt, in the scene "
                "directory, sparse/0 or sparse)");
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

TEST_CASE("COLMAP binary model in sparse/0 with transforms_test.json beside it; binary preferred over text") {
  TempDir dir;
  io::Split split;
  for (int i = 0; i < 3; ++i) {
    io::Frame f;
    f.name = "v" + std::to_string(i);
    f.image_path = dir / ("images/" + f.name + ".png");
    f.intrinsics = io::Intrinsics::from_fov_y(8, 6, 0.7);
    f.camera_to_world[3] = glm::dvec4(0.0, 0.0, 3.0 + i, 1.0);
    io::write_image(in_new_dir(f.image_path), io::Image(8, 6, 0.5f));
    io::write_mask(in_new_dir(dir / ("masks/" + f.name + ".png")), io::Mask(8, 6, true));
    split.frames.push_back(f);
  }
  io::write_colmap_binary(dir / "sparse/0", split, dir / "images");
  io::Split test;
  test.frames.push_back(split.frames[0]);
  io::write_transforms(dir / "transforms_test.json", test);
  const io::Scene s = io::load_scene(dir.path());
  CHECK(s.from_colmap);
  CHECK(s.colmap_format == "binary");
  CHECK(s.colmap_model == dir / "sparse/0");
  REQUIRE(s.train.frames.size() == 3);
  CHECK(s.train.frames[2].position().z == doctest::Approx(5.0));
  CHECK(s.train.frames[1].mask.count() == 48);
  CHECK(s.test.frames.size() == 1);
  CHECK(s.warnings.empty());
  write_text(dir / "sparse/0/cameras.txt", "1 PINHOLE 8 6 1 1 4 3\n");
  write_text(dir / "sparse/0/images.txt", "1 1 0 0 0 0 0 0 1 v0.png\n\n");
  CHECK(io::load_scene(dir.path()).train.frames.size() == 3);
  fs::remove(dir / "sparse/0/images.bin");
  const io::Scene text = io::load_scene(dir.path());
  CHECK(text.colmap_format == "text");
  CHECK(text.train.frames.size() == 1);
  fs::remove_all(dir / "sparse");
  CHECK(contains(error_of([&] { io::load_scene(dir.path()); }),
                 "transforms_train.json: file not found (and no COLMAP model, cameras.bin + images.bin or cameras.txt + "
                 "images.txt, in the scene directory, sparse/0 or sparse)"));
}

namespace {

// 4 x 2 RGBA image: alpha 255 on the left half, 0 on the right; the right half keeps its colour.
io::Image8 rgba_image(std::uint8_t background = 200) {
  io::Image8 im{4, 2, 4, {}};
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 4; ++x) {
      const std::uint8_t v = x < 2 ? 60 : background;
      im.data.insert(im.data.end(), {v, v, v, std::uint8_t(x < 2 ? 255 : 0)});
    }
  return im;
}

void write_frames(const fs::path& dir, const std::string& ext) {
  write_text(dir / "transforms_train.json",
             std::string(R"({"camera_angle_x": 0.8, "w": 4, "h": 2, "frames": [{"file_path": "images/a)") + ext +
                 R"(", "transform_matrix": )" + identity_at(3) + "}]}");
}

}  // namespace

TEST_CASE("masks from the alpha channel: automatic when there is no mask file, or asked for") {
  TempDir dir;
  io::write_png8(in_new_dir(dir / "images/a.png"), rgba_image());
  write_frames(dir.path(), ".png");
  io::Scene s = io::load_scene(dir.path());
  const io::Frame& f = s.train.frames[0];
  CHECK(f.mask_source == io::MaskSource::alpha);
  CHECK(f.has_mask());
  CHECK(f.mask.inside == std::vector<std::uint8_t>{1, 1, 0, 0, 1, 1, 0, 0});
  CHECK(f.image.at(3, 0).x == doctest::Approx(io::srgb_to_linear(200.0f / 255.0f)));  // the colour is kept
  CHECK_FALSE(contains(joined(s.warnings), "has no mask"));
  // a mask file wins over the alpha channel unless alpha is asked for
  io::Mask file_mask(4, 2);
  file_mask.inside[0] = 1;
  io::write_mask(in_new_dir(dir / "masks/a.png"), file_mask);
  CHECK(io::load_scene(dir.path()).train.frames[0].mask.count() == 1);
  io::LoadOptions alpha;
  alpha.masks.source = io::MaskSource::alpha;
  CHECK(io::load_scene(dir.path(), alpha).train.frames[0].mask.count() == 4);
  // cameras only: the source is decided from the header, no pixels read
  io::LoadOptions cameras = alpha;
  cameras.read_pixels = false;
  const io::Scene c = io::load_scene(dir.path(), cameras);
  CHECK(c.train.frames[0].mask_source == io::MaskSource::alpha);
  CHECK(c.train.frames[0].mask.width == 0);
  // none: no masks, no warnings about them
  io::LoadOptions none;
  none.masks.source = io::MaskSource::none;
  const io::Scene n = io::load_scene(dir.path(), none);
  CHECK_FALSE(n.train.frames[0].has_mask());
  CHECK_FALSE(contains(joined(n.warnings), "has no mask"));
}

TEST_CASE("alpha masks: an image without alpha is an error when alpha is asked for; opaque and black backgrounds warned") {
  TempDir dir;
  io::write_image(in_new_dir(dir / "images/a.exr"), io::Image(4, 2, 0.5f));
  write_frames(dir.path(), ".exr");
  io::LoadOptions alpha;
  alpha.masks.source = io::MaskSource::alpha;
  CHECK(error_of([&] { io::load_scene(dir.path(), alpha); }) ==
        (dir / "images/a.exr").string() + ": the image has no alpha channel to take the mask from (masks: alpha; only "
                                          "8-bit images such as PNG carry one here)");
  // automatic, an EXR without mask file: no mask, a warning
  CHECK(contains(joined(io::load_scene(dir.path()).warnings), "frames[0] (a) has no mask"));
  // an opaque alpha channel is no mask (automatic)
  TempDir opaque;
  io::Image8 im = rgba_image();
  for (std::size_t p = 3; p < im.data.size(); p += 4) im.data[p] = 255;
  io::write_png8(in_new_dir(opaque / "images/a.png"), im);
  write_frames(opaque.path(), ".png");
  const io::Scene o = io::load_scene(opaque.path());
  CHECK_FALSE(o.train.frames[0].has_mask());
  CHECK(contains(joined(o.warnings), "images/a.png: the alpha channel is opaque everywhere, so it is no mask"));
  // a cut-out: every background pixel black
  TempDir cut;
  io::write_png8(in_new_dir(cut / "images/a.png"), rgba_image(0));
  write_frames(cut.path(), ".png");
  const io::Scene k = io::load_scene(cut.path());
  CHECK(k.train.frames[0].mask.count() == 4);
  CHECK(contains(joined(k.warnings), "every pixel outside the alpha mask is black"));
  // the level: alpha 128 is object at the default level (127), not at 200
  io::Image8 soft = rgba_image();
  soft.data[3] = 128;
  io::write_png8(cut / "images/a.png", soft);
  io::LoadOptions high;
  high.masks.level = 200;
  CHECK(io::load_scene(cut.path()).train.frames[0].mask.count() == 4);
  CHECK(io::load_scene(cut.path(), high).train.frames[0].mask.count() == 3);
}

TEST_CASE("threshold masks and a mask folder") {
  TempDir dir;
  io::Image img(4, 2, 0.02f);  // dark backdrop
  img.set(1, 0, {0.9f, 0.1f, 0.1f});
  img.set(2, 1, {0.3f, 0.3f, 0.3f});
  io::write_image(in_new_dir(dir / "images/a.exr"), img);
  write_frames(dir.path(), ".exr");
  io::LoadOptions t;
  t.masks.source = io::MaskSource::threshold;
  t.masks.threshold = 0.5;  // sRGB 0.5 = linear 0.214
  io::Scene s = io::load_scene(dir.path(), t);
  CHECK(s.train.frames[0].mask_source == io::MaskSource::threshold);
  CHECK(s.train.frames[0].mask.inside == std::vector<std::uint8_t>{0, 1, 0, 0, 0, 0, 1, 0});
  t.masks.threshold = 0.7;  // linear 0.448: only the red pixel
  CHECK(io::load_scene(dir.path(), t).train.frames[0].mask.count() == 1);
  t.masks.below = true;  // a bright backdrop: object where darker
  CHECK(io::load_scene(dir.path(), t).train.frames[0].mask.count() == 7);
  // a mask folder elsewhere, by frame name
  TempDir elsewhere;
  io::Mask m(4, 2);
  m.inside[5] = 1;
  io::write_mask(in_new_dir(elsewhere / "a.png"), m);
  io::LoadOptions files;
  files.masks.source = io::MaskSource::files;
  files.masks.dir = elsewhere.path();
  const io::Scene f = io::load_scene(dir.path(), files);
  CHECK(f.train.frames[0].mask_path == elsewhere / "a.png");
  CHECK(f.train.frames[0].mask.inside[5] == 1);
  fs::remove(elsewhere / "a.png");
  CHECK(contains(joined(io::load_scene(dir.path(), files).warnings),
                 "frames[0] (a) has no mask in " + elsewhere.path().string()));
}
