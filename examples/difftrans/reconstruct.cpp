// difftrans reconstruct: the DiffTrans pipeline on a scene directory, stage
// by stage: --stages environment (a distant map or a near-field radiance
// field fitted to the out-of-mask pixels, stage_environment.cpp), geometry
// (stage 1, stage_geometry.cpp) and materials (stage 2, stage_materials.cpp).
// Stages run in the order given and read what earlier ones wrote into --out;
// reconstruct.json keeps the records of stages run by earlier invocations and
// is rewritten after each stage, and a stage stopped by SIGINT / SIGTERM
// leaves its checkpoint for the next run. The output folder is only ever seen
// whole (output_folder.hpp: RunFolder), even when the process is killed.
#include <chrono>
#include <exception>
#include <optional>
#include <sstream>
#include <string>
#include <vector>
#include <sys/resource.h>

#include "command.hpp"
#include "long_run.hpp"
#include "output_folder.hpp"
#include "scene_options.hpp"
#include "stages.hpp"
#include "views.hpp"

#include "difftrans/io/contact_sheet.hpp"
#include "difftrans/io/hdr.hpp"
#include "difftrans/io/image_file.hpp"
#include "difftrans/io/material.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/io/png.hpp"

namespace difftrans::cli {
namespace {

struct ReconstructOptions {
  fs::path scene, out;
  std::string stages = "environment";
  MaskCliOptions masks;
  ExposureCliOptions exposure;
  std::uint64_t seed = 0;  // 0: each stage's own default
};

// The stages compare their results with the scene's gt/ files at their end.
// A comparison is a report: a ground-truth file that cannot be read (or a mesh
// with no surface to measure) is found here, before any fitting, warned about
// and left out, so that it cannot fail a run after the work is done. Returns
// the warnings, also recorded in reconstruct.json.
std::vector<std::string> check_ground_truth(io::Scene& scene) {
  std::vector<std::string> skipped;
  const auto check = [&](fs::path& file, const char* what, const auto& read) {
    if (file.empty()) return;
    try {
      read(file);
    } catch (const std::exception& e) {
      skipped.push_back(std::string(e.what()) + "; the comparison with the ground-truth " + what + " is left out");
      warn(skipped.back());
      file.clear();
    }
  };
  check(scene.gt.mesh, "mesh", [](const fs::path& f) {
    const io::Mesh mesh = io::read_mesh(f);
    double area = 0.0;
    for (const Vec3i& t : mesh.triangles)
      area += 0.5 * glm::length(glm::cross(Vec3d(mesh.positions[size_t(t.y)] - mesh.positions[size_t(t.x)]),
                                           Vec3d(mesh.positions[size_t(t.z)] - mesh.positions[size_t(t.x)])));
    if (!(area > 0.0)) throw io::Error(f, "no surface to compare with (" + std::to_string(mesh.triangles.size()) +
                                              " triangles of total area 0)");
  });
  check(scene.gt.material, "material", [](const fs::path& f) { io::read_material(f); });
  check(scene.gt.envmap, "environment map", [](const fs::path& f) { io::read_image(f); });
  return skipped;
}

}  // namespace

void add_run_options(CLI::App* cmd, RunOptions& opt) {
  cmd->add_flag("--restart", opt.restart,
                "Ignore the checkpoints and finished results in --out (geometry, materials) and start afresh");
  cmd->add_option("--checkpoint-every", opt.checkpoint_every,
                  "Iterations between checkpoints of geometry and materials (also at least once a minute and on "
                  "SIGINT / SIGTERM)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--device", opt.device,
                  "where stage 2 (materials) traces its training rays: cpu (the host's threads), cuda (the GPU; fails "
                  "at once without one) or auto (the GPU when there is one); the other stages run on the host")
      ->capture_default_str()
      ->check(CLI::IsMember({"cpu", "cuda", "auto"}));
}

void add_reconstruct(CLI::App& app) {
  auto opt = std::make_shared<ReconstructOptions>();
  auto environment = std::make_shared<pipeline::EnvironmentConfig>();
  auto geometry = std::make_shared<GeometryOptions>();
  auto materials = std::make_shared<pipeline::Stage2Config>();
  auto run = std::make_shared<RunOptions>();
  CLI::App* cmd = app.add_subcommand("reconstruct", "Reconstruct a transparent object from a scene directory");
  cmd->add_option("scene", opt->scene, "Scene directory (transforms_train.json, images, masks)")->required();
  cmd->add_option("--out", opt->out, "Output directory")->required();
  cmd->add_option("--stages", opt->stages, "Stages to run, comma-separated: environment, geometry, materials")->capture_default_str();
  add_mask_options(cmd, opt->masks);
  add_exposure_options(cmd, opt->exposure);
  add_environment_options(cmd, *environment);
  add_geometry_options(cmd, *geometry);
  add_materials_options(cmd, *materials);
  add_run_options(cmd, *run);
  cmd->add_option("--seed", opt->seed,
                  "Seed of every random choice of the stages (view batches, ray batches, jitter); with the same seed "
                  "a run repeats bit for bit, on any number of threads (0: the stages' defaults)")
      ->capture_default_str();
  cmd->callback([opt, environment, geometry, materials, run] {
    check_device(run->device);
    if (opt->seed != 0) environment->field_seed = geometry->config.seed = materials->seed = opt->seed;
    std::stringstream ss(opt->stages);
    std::vector<std::string> stages;
    for (std::string s; std::getline(ss, s, ',');)
      if (!s.empty()) stages.push_back(s);
    for (const auto& s : stages)
      if (s != "environment" && s != "geometry" && s != "materials")
        throw std::runtime_error("--stages: '" + s + "' is not a stage (stages: environment, geometry, materials)");
    io::LoadOptions load;
    load.masks = mask_options(opt->masks);
    progress("reconstruct: loading " + opt->scene.string());
    io::Scene scene = io::load_scene(opt->scene, load);
    for (const auto& w : scene.warnings) warn(w);
    const std::vector<std::string> gt_skipped = check_ground_truth(scene);
    const io::Json exposure = apply_exposure_option(scene, opt->exposure);
    if (exposure["source"] != "none" || exposure.contains("reason"))
      progress("reconstruct: exposure " + exposure["scale"].dump() + " (" + exposure["source"].get<std::string>() +
               (exposure.contains("reason") ? ": " + exposure["reason"].get<std::string>() : std::string()) + ")");
    // Everything is written into OUT.partial, a copy of OUT, and published as
    // OUT in one step after each stage and each checkpoint (output_folder.hpp):
    // a run killed at any moment leaves OUT as its last publication made it.
    RunFolder folder(opt->out);
    io::Json result = io::Json::object();
    const fs::path record = folder.work() / "reconstruct.json";
    if (fs::exists(record)) {  // keep the stages an earlier invocation ran
      try {
        result = io::read_json(record);
      } catch (const std::exception& e) {
        warn(folder.shown(record).string() + " is unreadable (" + e.what() + "); starting a new record");
      }
    }
    result["scene"] = opt->scene.string();
    result["masks"] = describe(load.masks);
    result["exposure"] = exposure;
    if (!gt_skipped.empty()) result["ground_truth_skipped"] = gt_skipped;
    else result.erase("ground_truth_skipped");
    // the record of every finished stage is published before the next one
    // starts; during a fit SIGINT / SIGTERM make it save its checkpoint and
    // stop (long_run.hpp), which is published too; elsewhere they end the
    // program as usual, and OUT keeps the last publication
    try {
      for (const auto& s : stages) {
        if (s == "environment") {
          result["environment"] = environment_stage(scene, folder.work(), *environment);
        } else if (s == "geometry") {
          result["geometry"] = geometry_stage(scene, folder, *geometry, *run);
        } else if (s == "materials") {
          result["materials"] = materials_stage(scene, folder, *materials, *run);
        }
        io::write_json(record, result);
        folder.commit();
      }
    } catch (const Interrupted&) {
      folder.commit();
      throw;
    }
    emit_json(result, std::nullopt);
  });
}

}  // namespace difftrans::cli
