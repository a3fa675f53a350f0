// difftrans reconstruct: the DiffTrans pipeline on a scene directory, stage
// by stage. Implemented so far: --stages environment (a distant map or a
// near-field radiance field fitted to the out-of-mask pixels,
// stage_environment.cpp) and geometry (stage 1, stage_geometry.cpp).
// Materials (stage 2) follow in a later version.
#include <chrono>
#include <sstream>
#include <sys/resource.h>

#include "command.hpp"
#include "stages.hpp"
#include "views.hpp"

#include "difftrans/io/contact_sheet.hpp"
#include "difftrans/io/hdr.hpp"
#include "difftrans/io/png.hpp"
#include "difftrans/render/background.hpp"

namespace difftrans::cli {
namespace {

struct ReconstructOptions {
  fs::path scene, out;
  std::string stages = "environment";
};

}  // namespace

void add_reconstruct(CLI::App& app) {
  auto opt = std::make_shared<ReconstructOptions>();
  auto environment = std::make_shared<EnvironmentStageOptions>();
  auto geometry = std::make_shared<GeometryStageOptions>();
  CLI::App* cmd = app.add_subcommand("reconstruct", "Reconstruct a transparent object from a scene directory");
  cmd->add_option("scene", opt->scene, "Scene directory (transforms_train.json, images, masks)")->required();
  cmd->add_option("--out", opt->out, "Output directory")->required();
  cmd->add_option("--stages", opt->stages, "Stages to run, comma-separated: environment, geometry")->capture_default_str();
  add_environment_options(cmd, *environment);
  add_geometry_options(cmd, *geometry);
  cmd->callback([opt, environment, geometry] {
    std::stringstream ss(opt->stages);
    std::vector<std::string> stages;
    for (std::string s; std::getline(ss, s, ',');)
      if (!s.empty()) stages.push_back(s);
    for (const auto& s : stages)
      if (s != "environment" && s != "geometry")
        throw std::runtime_error("--stages: '" + s +
                                 "' is not available in this version (available: environment, geometry)");
    progress("reconstruct: loading " + opt->scene.string());
    const io::Scene scene = io::load_scene(opt->scene);
    for (const auto& w : scene.warnings) warn(w);
    fs::create_directories(opt->out);
    io::Json result;
    result["scene"] = opt->scene.string();
    for (const auto& s : stages)
      if (s == "environment") {
        result["environment"] = environment_stage(scene, opt->out, *environment);
      } else if (s == "geometry") {
        result["geometry"] = geometry_stage(scene, opt->out, *geometry);
      }
    emit_json(result, opt->out / "reconstruct.json");
  });
}

}  // namespace difftrans::cli
