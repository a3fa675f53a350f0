// The scene directory of docs/scene-format.md: transforms_train.json / transforms_test.json
// (NeRF-synthetic convention, masks per frame), optional scene.json, gt/, or a
// COLMAP model (binary or text); loaded with or without pixels, and written back.
#pragma once

#include <optional>

#include "difftrans/io/colmap.hpp"
#include "difftrans/io/json.hpp"
#include "difftrans/io/mesh.hpp"

namespace difftrans::io {

enum class EnvironmentKind { distant, near };

inline const char* to_string(EnvironmentKind kind) { return kind == EnvironmentKind::near ? "near" : "distant"; }

// What scene.json says (all optional).
struct SceneSettings {
  std::optional<Box> aabb;
  EnvironmentKind environment = EnvironmentKind::distant;
};

// Ground truth of synthetic scenes (paths empty where the file is absent).
struct GroundTruth {
  bool present = false;  // the gt/ folder exists
  std::filesystem::path mesh, material, envmap;
};

struct Scene {
  std::filesystem::path dir;
  Split train;
  Split test;                  // empty when there is no transforms_test.json
  bool from_colmap = false;    // training cameras came from a COLMAP model
  std::filesystem::path colmap_model;  // its folder (DIR, DIR/sparse/0 or DIR/sparse)
  std::string colmap_format;           // "binary" or "text"
  bool has_scene_json = false;
  SceneSettings settings;
  GroundTruth gt;
  std::vector<std::string> warnings;
};

namespace detail {

inline std::filesystem::path resolve(const std::filesystem::path& base, const std::string& relative) {
  const std::filesystem::path p(relative);
  return (p.is_absolute() ? p : base / p).lexically_normal();
}

// Reads intrinsics for a frame: keys on the frame override the file's.
inline Intrinsics read_intrinsics(const JsonReader& top, const JsonReader& frame, const Frame& f) {
  const auto pick = [&](const std::string& key) -> const JsonReader* {
    if (frame.has(key)) return &frame;
    if (top.has(key)) return &top;
    return nullptr;
  };
  Intrinsics k;
  const JsonReader* w = pick("w");
  const JsonReader* h = pick("h");
  if (w && h) {
    k.width = w->integer("w");
    k.height = h->integer("h");
  } else if (w || h) {
    (w ? w : h)->fail(w ? "h" : "w", "missing (w and h go together)");
  } else {  // no size declared (original NeRF-synthetic): the image's own
    const Vec2i size = image_size(f.image_path);
    k.width = size.x;
    k.height = size.y;
  }
  if (k.width <= 0 || k.height <= 0)
    (w ? *w : top).fail("w", "image size " + size_text(k.width, k.height) + " is not positive");
  if (const JsonReader* fl = pick("fl_x")) {
    k.fx = fl->number("fl_x");
    const JsonReader* fy = pick("fl_y");
    k.fy = fy ? fy->number("fl_y") : k.fx;
  } else if (const JsonReader* ax = pick("camera_angle_x")) {
    const double angle = ax->number("camera_angle_x");
    if (!(angle > 0.0 && angle < 3.14159)) ax->fail("camera_angle_x", "must lie in (0, pi) radians");
    k.fx = 0.5 * k.width / std::tan(0.5 * angle);
    k.fy = k.fx;
    if (const JsonReader* ay = pick("camera_angle_y")) {
      const double angle_y = ay->number("camera_angle_y");
      if (!(angle_y > 0.0 && angle_y < 3.14159)) ay->fail("camera_angle_y", "must lie in (0, pi) radians");
      k.fy = 0.5 * k.height / std::tan(0.5 * angle_y);
    }
  } else {
    top.fail("camera_angle_x", "missing (give camera_angle_x or fl_x)");
  }
  const JsonReader* cx = pick("cx");
  const JsonReader* cy = pick("cy");
  k.cx = cx ? cx->number("cx") : 0.5 * k.width;
  k.cy = cy ? cy->number("cy") : 0.5 * k.height;
  return k;
}

}  // namespace detail

// Loads one transforms_*.json. Paths are relative to the JSON file's folder;
// file_path may omit the extension (.exr, .hdr, .png, .jpg are tried); a
// frame without mask_path uses masks/NAME.png next to the JSON when it exists
// (options.masks says whether masks come from files, the alpha channel or a
// threshold, and may name another mask folder).
inline Split load_transforms(const std::filesystem::path& path, const LoadOptions& options = {},
                             std::vector<std::string>* warnings = nullptr) {
  const Json json = read_json(path);
  const JsonReader top(json, path);
  top.require_object();
  const Json& frames = top.at("frames");
  if (!frames.is_array()) top.fail("frames", "expected an array");
  if (frames.empty()) top.fail("frames", "no frames");
  const std::filesystem::path base = path.parent_path();
  Split split;
  split.file = path;
  bool warned_distortion = false;
  for (size_t i = 0; i < frames.size(); ++i) {
    try {
      const JsonReader fr = top.child("frames").element(i);
      fr.require_object();
      Frame f;
      const std::string file_path = fr.string("file_path");
      f.image_path = detail::find_image(detail::resolve(base, file_path));
      if (f.image_path.empty())
        fr.fail("file_path", "no image " + detail::excerpt(file_path) + " (tried it as given and with .exr, .hdr, .png, .jpg) in " +
                                 base.string());
      f.name = f.image_path.stem().string();
      f.environment_only = fr.boolean("environment_only", false);
      std::filesystem::path mask_file;
      const MaskSource source = options.masks.source;
      if (source == MaskSource::files || source == MaskSource::automatic) {
        std::error_code ec;
        if (!options.masks.dir.empty()) {
          mask_file = mask_in_dir(options.masks.dir, f);
        } else if (fr.has("mask_path")) {
          const std::string mask_path = fr.string("mask_path");
          mask_file = detail::resolve(base, mask_path);
          if (!std::filesystem::is_regular_file(mask_file, ec)) {
            std::filesystem::path with_png = mask_file;
            with_png += ".png";
            if (!std::filesystem::is_regular_file(with_png, ec))
              fr.fail("mask_path", "no mask " + detail::excerpt(mask_path) + " in " + base.string());
            mask_file = with_png;
          }
        } else {
          const auto guess = base / "masks" / (f.name + ".png");
          if (std::filesystem::is_regular_file(guess, ec)) mask_file = guess;
        }
      }
      if (!choose_mask(f, mask_file, options.masks) && source != MaskSource::none && !f.environment_only && warnings)
        warnings->push_back(path.string() + ": frames[" + std::to_string(i) + "] (" + f.name + ") has no mask" +
                            (options.masks.dir.empty() ? std::string() : " in " + options.masks.dir.string()));
      f.intrinsics = detail::read_intrinsics(top, fr, f);
      check_intrinsics(f.intrinsics, path, fr.where());
      if (!warned_distortion && warnings)
        for (const char* key : {"k1", "k2", "k3", "p1", "p2"})
          if ((fr.has(key) && fr.number(key) != 0.0) || (top.has(key) && top.number(key) != 0.0)) {
            warnings->push_back(path.string() + ": lens distortion (" + key + ") is ignored");
            warned_distortion = true;
            break;
          }
      const bool rows3 = fr.at("transform_matrix").is_array() && fr.at("transform_matrix").size() == 3;
      const std::vector<double> m = fr.matrix("transform_matrix", rows3 ? 3 : 4, 4);
      for (int r = 0; r < (rows3 ? 3 : 4); ++r)
        for (int c = 0; c < 4; ++c) f.camera_to_world[c][r] = m[size_t(r) * 4 + size_t(c)];
      check_camera_matrix(f.camera_to_world, path, fr.field("transform_matrix"));
      if (options.read_pixels) read_frame_pixels(f, path, options.masks, warnings);
      else if (options.check_sizes) check_frame_headers(f, path);
      split.frames.push_back(std::move(f));
    } catch (const Error& e) {
      if (!options.skip_bad_frames) throw;
      if (warnings) warnings->push_back(std::string("skipped a frame: ") + e.what());
    }
  }
  return split;
}

// Reads scene.json: {"aabb": [[x0,y0,z0],[x1,y1,z1]], "environment": "distant"|"near"}.
inline SceneSettings load_scene_settings(const std::filesystem::path& path) {
  const Json json = read_json(path);
  const JsonReader top(json, path);
  top.require_object();
  SceneSettings s;
  if (top.has("aabb")) {
    const auto m = top.matrix("aabb", 2, 3);
    Box box;
    box.lo = {m[0], m[1], m[2]};
    box.hi = {m[3], m[4], m[5]};
    if (!(box.lo.x < box.hi.x && box.lo.y < box.hi.y && box.lo.z < box.hi.z))
      top.fail("aabb", "the first corner must be below the second on every axis");
    s.aabb = box;
  }
  const std::string env = top.string("environment", "distant");
  if (env == "distant") s.environment = EnvironmentKind::distant;
  else if (env == "near") s.environment = EnvironmentKind::near;
  else top.fail("environment", detail::excerpt(env) + " is neither \"distant\" nor \"near\"");
  return s;
}

// Loads a scene directory: transforms_train.json (required) and
// transforms_test.json, or else a COLMAP model, binary (cameras.bin,
// images.bin) or text (cameras.txt, images.txt), in DIR, DIR/sparse/0 or
// DIR/sparse with images in DIR/images and masks in DIR/masks (the training
// views; a transforms_test.json beside it gives held-out views); scene.json; gt/.
inline Scene load_scene(const std::filesystem::path& dir, const LoadOptions& options = {}) {
  Scene scene;
  scene.dir = dir;
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    throw Error(dir, std::filesystem::exists(dir, ec) ? "is not a directory" : "scene directory not found");
  const auto train = dir / "transforms_train.json";
  const auto test = dir / "transforms_test.json";
  if (std::filesystem::exists(train, ec)) {
    scene.train = load_transforms(train, options, &scene.warnings);
    if (std::filesystem::exists(test, ec)) scene.test = load_transforms(test, options, &scene.warnings);
    else scene.warnings.push_back(test.string() + ": not found; the scene has no held-out views");
  } else {
    for (const auto& candidate : {dir, dir / "sparse" / "0", dir / "sparse"}) {
      scene.colmap_format = colmap_model_format(candidate);
      if (!scene.colmap_format.empty()) {
        scene.colmap_model = candidate;
        break;
      }
    }
    if (scene.colmap_model.empty())
      throw Error(train, "file not found (and no COLMAP model, cameras.bin + images.bin or cameras.txt + images.txt, "
                         "in the scene directory, sparse/0 or sparse)");
    const auto masks = dir / "masks";
    scene.train = load_colmap(scene.colmap_model, dir / "images",
                              std::filesystem::is_directory(masks, ec) ? masks : std::filesystem::path(), options,
                              &scene.warnings);
    scene.from_colmap = true;
    if (std::filesystem::exists(test, ec)) scene.test = load_transforms(test, options, &scene.warnings);
  }
  if (scene.train.frames.empty()) throw Error(train, "no usable frames");
  const auto settings = dir / "scene.json";
  if (std::filesystem::exists(settings, ec)) {
    scene.settings = load_scene_settings(settings);
    scene.has_scene_json = true;
  }
  const auto gt = dir / "gt";
  scene.gt.present = std::filesystem::is_directory(gt, ec);
  if (scene.gt.present) {
    const auto pick = [&](const char* name) {
      const auto p = gt / name;
      return std::filesystem::is_regular_file(p, ec) ? p : std::filesystem::path();
    };
    scene.gt.mesh = pick("mesh.obj");
    if (scene.gt.mesh.empty()) scene.gt.mesh = pick("mesh.ply");
    scene.gt.material = pick("material.json");
    scene.gt.envmap = pick("envmap.hdr");
    if (scene.gt.envmap.empty()) scene.gt.envmap = pick("envmap.exr");
  }
  // Frames whose masks and images disagree are caught per frame; here, the
  // whole-scene checks.
  for (const Split* s : {&scene.train, &scene.test}) {
    size_t objects = 0;
    for (const auto& f : s->frames) objects += !f.environment_only;
    if (!s->frames.empty() && objects == 0)
      scene.warnings.push_back(s->file.string() + ": every frame is environment_only");
  }
  // masks read, none with an object pixel: nothing to reconstruct (each empty
  // mask was warned about as it was read)
  size_t masks = 0, empty = 0;
  std::filesystem::path first;
  for (const auto& f : scene.train.frames)
    if (!f.environment_only && !f.mask.inside.empty()) {
      if (masks++ == 0) first = mask_origin(f);
      empty += !has_foreground(f.mask);
    }
  if (masks > 0 && empty == masks)
    throw Error(scene.train.file, "no foreground pixel in any mask: the " + std::to_string(masks) +
                                      " masks of the training views are all empty (the first: " +
                                      first.string() + ")");
  return scene;
}

// Writes a transforms_*.json for the frames of a split, with paths relative
// to the JSON's folder. Intrinsics shared by every frame are written once at
// the top (fl_x, fl_y, cx, cy, w, h and camera_angle_x), else per frame.
inline void write_transforms(const std::filesystem::path& path, const Split& split) {
  const std::filesystem::path base = path.parent_path();
  const auto relative = [&](const std::filesystem::path& p) {
    return p.lexically_relative(base.empty() ? std::filesystem::path(".") : base).generic_string();
  };
  const auto put_intrinsics = [](Json& j, const Intrinsics& k) {
    j["w"] = k.width;
    j["h"] = k.height;
    j["fl_x"] = k.fx;
    j["fl_y"] = k.fy;
    j["cx"] = k.cx;
    j["cy"] = k.cy;
    j["camera_angle_x"] = k.fov_x();
  };
  const auto same = [](const Intrinsics& a, const Intrinsics& b) {
    return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy;
  };
  bool shared = !split.frames.empty();
  for (const auto& f : split.frames) shared = shared && same(f.intrinsics, split.frames.front().intrinsics);
  Json json = Json::object();
  if (shared) put_intrinsics(json, split.frames.front().intrinsics);
  Json frames = Json::array();
  for (const auto& f : split.frames) {
    Json fr = Json::object();
    fr["file_path"] = relative(f.image_path);
    if (!f.mask_path.empty()) fr["mask_path"] = relative(f.mask_path);
    if (!shared) put_intrinsics(fr, f.intrinsics);
    if (f.environment_only) fr["environment_only"] = true;
    Json rows = Json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({f.camera_to_world[0][r], f.camera_to_world[1][r], f.camera_to_world[2][r],
                                                f.camera_to_world[3][r]});
    fr["transform_matrix"] = rows;
    frames.push_back(fr);
  }
  json["frames"] = frames;
  write_json(path, json);
}

inline void write_scene_settings(const std::filesystem::path& path, const SceneSettings& settings) {
  Json json = Json::object();
  if (settings.aabb)
    json["aabb"] = {{settings.aabb->lo.x, settings.aabb->lo.y, settings.aabb->lo.z},
                    {settings.aabb->hi.x, settings.aabb->hi.y, settings.aabb->hi.z}};
  json["environment"] = to_string(settings.environment);
  write_json(path, json);
}

}  // namespace difftrans::io
