// difftrans info SCENE_DIR: loads a scene directory (docs/scene-format.md) and prints a
// summary: views per split, resolution, cameras, masks, scene.json, gt/, and
// every bad input as a warning (bad frames are reported and left out).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <memory>
#include <set>

#include "command.hpp"
#include "scene_options.hpp"
#include "difftrans/io/dataset.hpp"

namespace difftrans::cli {
namespace {

namespace fs = std::filesystem;

struct InfoOptions {
  std::string dir;
  bool cameras_only = false;
  bool json = false;
  MaskCliOptions masks;
};

std::string fixed(double v, int digits = 3) {
  char s[64];
  std::snprintf(s, sizeof(s), "%.*f", digits, v);
  return s;
}

io::Json summarize(const io::Split& split) {
  io::Json j = io::Json::object();
  j["file"] = split.file.string();
  j["views"] = split.frames.size();
  std::size_t env_only = 0, with_mask = 0, mask_pixels = 0, pixels = 0;
  std::map<std::string, std::size_t> mask_sources;
  std::set<std::pair<int, int>> sizes;
  std::set<std::string> fovs;
  double r_min = INFINITY, r_max = 0.0, off_axis_max = 0.0;
  for (const auto& f : split.frames) {
    env_only += f.environment_only;
    with_mask += f.has_mask();
    if (f.has_mask()) ++mask_sources[io::to_string(f.mask_source)];
    sizes.insert({f.intrinsics.width, f.intrinsics.height});
    fovs.insert(fixed(f.intrinsics.fov_y() * 180.0 / M_PI, 2));
    const Vec3d c = f.position();
    const double r = glm::length(c);
    r_min = std::min(r_min, r);
    r_max = std::max(r_max, r);
    // Angle between the viewing direction and the direction to the origin.
    if (r > 0.0) {
      const double cosine = std::clamp(glm::dot(glm::normalize(f.forward()), -c / r), -1.0, 1.0);
      off_axis_max = std::max(off_axis_max, std::acos(cosine) * 180.0 / M_PI);
    }
    if (!f.mask.inside.empty()) {
      mask_pixels += f.mask.count();
      pixels += f.mask.inside.size();
    }
  }
  j["environment_only"] = env_only;
  j["with_mask"] = with_mask;
  j["mask_sources"] = mask_sources;
  io::Json res = io::Json::array();
  for (const auto& [w, h] : sizes) res.push_back({w, h});
  j["resolutions"] = res;
  j["fov_y_degrees"] = std::vector<std::string>(fovs.begin(), fovs.end());
  if (!split.frames.empty()) {
    j["camera_distance"] = {r_min, r_max};
    j["max_angle_to_origin_degrees"] = off_axis_max;
  }
  if (pixels > 0) j["mask_coverage"] = double(mask_pixels) / double(pixels);
  return j;
}

void print_split(const char* name, const io::Json& s) {
  std::printf("%s: %s\n", name, s["file"].get<std::string>().c_str());
  std::printf("  views: %zu (%zu environment-only, %zu with a mask)\n", s["views"].get<std::size_t>(),
              s["environment_only"].get<std::size_t>(), s["with_mask"].get<std::size_t>());
  std::string sources;
  for (const auto& [name, n] : s["mask_sources"].items())
    sources += (sources.empty() ? "" : ", ") + std::to_string(n.get<std::size_t>()) + " " + name;
  if (!sources.empty()) std::printf("  masks from: %s\n", sources.c_str());
  std::string res;
  for (const auto& r : s["resolutions"]) res += (res.empty() ? "" : ", ") + r[0].dump() + " x " + r[1].dump();
  std::printf("  resolution: %s\n", res.c_str());
  std::string fov;
  for (const auto& f : s["fov_y_degrees"]) fov += (fov.empty() ? "" : ", ") + f.get<std::string>();
  std::printf("  vertical field of view: %s degrees\n", fov.c_str());
  if (s.contains("camera_distance"))
    std::printf("  cameras: %s to %s from the origin; view axis at most %s degrees off the origin\n",
                fixed(s["camera_distance"][0].get<double>()).c_str(), fixed(s["camera_distance"][1].get<double>()).c_str(),
                fixed(s["max_angle_to_origin_degrees"].get<double>(), 2).c_str());
  if (s.contains("mask_coverage"))
    std::printf("  mask coverage: %s%% of pixels\n", fixed(100.0 * s["mask_coverage"].get<double>(), 2).c_str());
}

void run(const InfoOptions& o) {
  io::LoadOptions options;
  options.read_pixels = !o.cameras_only;
  options.skip_bad_frames = true;
  options.masks = mask_options(o.masks);
  if (!o.json) progress("info: loading " + o.dir + (o.cameras_only ? " (cameras only)" : ""));
  const io::Scene scene = io::load_scene(o.dir, options);
  io::Json j = io::Json::object();
  j["dir"] = scene.dir.string();
  j["source"] = scene.from_colmap ? "colmap " + scene.colmap_format : std::string("transforms");
  j["train"] = summarize(scene.train);
  if (!scene.test.frames.empty()) j["test"] = summarize(scene.test);
  j["environment"] = io::to_string(scene.settings.environment);
  if (scene.settings.aabb)
    j["aabb"] = {{scene.settings.aabb->lo.x, scene.settings.aabb->lo.y, scene.settings.aabb->lo.z},
                 {scene.settings.aabb->hi.x, scene.settings.aabb->hi.y, scene.settings.aabb->hi.z}};
  io::Json gt = io::Json::object();
  gt["present"] = scene.gt.present;
  if (!scene.gt.mesh.empty()) gt["mesh"] = scene.gt.mesh.string();
  if (!scene.gt.material.empty()) gt["material"] = scene.gt.material.string();
  if (!scene.gt.envmap.empty()) gt["envmap"] = scene.gt.envmap.string();
  j["gt"] = gt;
  j["warnings"] = scene.warnings;
  if (o.json) {
    std::cout << j.dump(2) << std::endl;
    return;
  }
  std::printf("scene: %s (%s)\n", scene.dir.string().c_str(),
              scene.from_colmap ? ("COLMAP " + scene.colmap_format + " model in " + scene.colmap_model.string()).c_str()
                                : "transforms_*.json");
  print_split("train", j["train"]);
  if (j.contains("test")) print_split("test", j["test"]);
  std::printf("environment: %s%s\n", io::to_string(scene.settings.environment),
              scene.has_scene_json ? "" : " (default; no scene.json)");
  if (scene.settings.aabb)
    std::printf("aabb: %s\n", j["aabb"].dump().c_str());
  if (scene.gt.present)
    std::printf("ground truth: mesh %s, material %s, envmap %s\n",
                scene.gt.mesh.empty() ? "(none)" : scene.gt.mesh.string().c_str(),
                scene.gt.material.empty() ? "(none)" : scene.gt.material.string().c_str(),
                scene.gt.envmap.empty() ? "(none)" : scene.gt.envmap.string().c_str());
  else
    std::printf("ground truth: none (no gt/ folder)\n");
  std::printf("warnings: %zu\n", scene.warnings.size());
  for (const auto& w : scene.warnings) std::printf("  warning: %s\n", w.c_str());
}

}  // namespace

void add_info(CLI::App& app) {
  auto o = std::make_shared<InfoOptions>();
  CLI::App* cmd = app.add_subcommand("info", "Load a scene directory and print a summary (bad inputs as warnings)");
  cmd->add_option("SCENE_DIR", o->dir, "scene directory (transforms_*.json or a COLMAP model, binary or text)")->required();
  cmd->add_flag("--cameras-only", o->cameras_only, "read cameras and paths only, not the pixels");
  cmd->add_flag("--json", o->json, "print the summary as JSON");
  add_mask_options(cmd, o->masks);
  cmd->callback([o] { run(*o); });
}

}  // namespace difftrans::cli
