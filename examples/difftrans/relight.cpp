// difftrans relight: an object (a reconstruction, or the ground truth) under
// other environment maps (docs/benchmark-scenes.md: the three maps not used for
// training, 10 test views each), compared with the scene's ground truth
// rendered under the same maps: images, metrics and a contact sheet per map.
#include <cmath>
#include <memory>
#include <set>
#include <string>

#include "output_folder.hpp"
#include "views.hpp"

namespace difftrans::cli {
namespace {

struct RelightOptions {
  std::string mesh, scene, out, data, device = "cpu";
  MaterialOptions material;
  std::vector<std::string> envs;
  bool all_envs = false;
  int views = io::relighting_views;
  int max_depth = 16, spp_axis = 4, sheet_rows = 4;
  bool overwrite = false;
};

bool same_file_contents(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::file_size(a, ec) != fs::file_size(b, ec) || ec) return false;
  return io::detail::read_file_text(a) == io::detail::read_file_text(b);
}

// The training environment's file name: gt/synth.json's "environment", else
// the shared map whose bytes equal gt/envmap.hdr; empty when unknown.
std::string training_environment(const io::Scene& scene, const fs::path& data) {
  std::error_code ec;
  const fs::path synth = scene.dir / "gt" / "synth.json";
  if (fs::exists(synth, ec)) {
    const io::Json j = io::read_json(synth);
    if (j.contains("environment") && j["environment"].is_string()) return j["environment"].get<std::string>();
  }
  if (!scene.gt.envmap.empty())
    for (const auto& name : io::shared_environments())
      if (fs::exists(data / "envmaps" / name, ec) && same_file_contents(data / "envmaps" / name, scene.gt.envmap))
        return name;
  return "";
}

void run(const RelightOptions& o) {
  check_device(o.device);
  if (o.envs.empty() == !o.all_envs) throw CLI::ValidationError("give either --env (one or more) or --all-envs");
  const io::Material material = o.material.resolve();
  const io::Mesh mesh = load_mesh(o.mesh);
  io::LoadOptions lo;
  lo.read_pixels = false;
  const io::Scene scene = io::load_scene(o.scene, lo);
  for (const auto& w : scene.warnings) warn(w);
  const io::Split& split = scene.test.frames.empty() ? scene.train : scene.test;
  if (scene.test.frames.empty()) warn(o.scene + ": no test views; relighting from training views");

  std::vector<std::string> env_specs = o.envs;
  const fs::path data = data_dir(o.data);
  if (o.all_envs) {
    const std::string training = training_environment(scene, data);
    if (training.empty()) warn("the training environment is unknown; relighting under all four shared maps");
    else progress("relight: training environment " + training + "; using the other shared maps");
    for (const auto& name : io::relighting_environments(training)) env_specs.push_back((data / "envmaps" / name).string());
  }
  std::vector<Environment> envs;
  for (const auto& spec : env_specs) envs.push_back(load_environment(spec));

  // reference: the scene's ground truth, when it has one
  const bool has_truth = !scene.gt.mesh.empty() && !scene.gt.material.empty();
  if (!has_truth) warn(o.scene + ": no gt/mesh.obj and gt/material.json; renders only, no metrics");

  std::vector<View> views;
  for (int i : io::spread_indices(int(split.frames.size()), o.views)) views.push_back(view_from_frame(split.frames[size_t(i)]));

  std::vector<fs::path> inputs = {o.mesh, o.scene, o.material.material_file, o.material.absorption_grid};
  inputs.insert(inputs.end(), env_specs.begin(), env_specs.end());
  OutputDir out(o.out, o.overwrite, inputs);
  render::HostScene s = render::make_host_scene(mesh, material, fs::path(o.mesh).filename().string());
  // relighting the ground truth itself: its renders are the reference, no second pass
  std::error_code ec;
  const bool is_truth = has_truth && !o.material.material_file.empty() && !o.material.ior &&
                        o.material.absorption.empty() && o.material.absorption_grid.empty() &&
                        fs::equivalent(o.mesh, scene.gt.mesh, ec) && fs::equivalent(o.material.material_file, scene.gt.material, ec);
  if (is_truth) progress("relight: the object is the scene's ground truth; its renders are the reference");
  std::optional<render::HostScene> truth;
  if (has_truth && !is_truth) truth.emplace(render::make_host_scene(load_mesh(scene.gt.mesh), io::read_material(scene.gt.material), "gt"));
  const render::PassOptions options = render::reference_pass_options(o.max_depth, o.spp_axis);

  io::Json result = io::Json::object();
  io::Json per_env = io::Json::array();
  double sum_psnr = 0, sum_mask = 0, sum_ssim = 0;
  int n_mask = 0;  // environments with an in-mask PSNR (none where the views have no masks)
  const auto add_metrics = [&](const io::Json& entry) {
    sum_psnr += entry["psnr"].get<double>();
    if (entry["psnr_mask"].is_number()) sum_mask += entry["psnr_mask"].get<double>(), ++n_mask;
    sum_ssim += entry["ssim"].get<double>();
  };
  std::set<std::string> used_names;
  // the GPU tracers of the scene and of the truth: made once, their BVH kept, updated per environment
  std::unique_ptr<GpuViewTracer> gpu_scene, gpu_truth;
  for (std::size_t e = 0; e < envs.size(); ++e) {
    std::string name = envs[e].name();
    while (!used_names.insert(name).second) name += "_";
    progress("relight: environment " + std::to_string(e + 1) + "/" + std::to_string(envs.size()) + ": " + envs[e].spec);
    const fs::path dir = out.path() / name;
    apply_environment(s, envs[e]);
    GpuViewTracer* gpu = gpu_tracer_kept(gpu_scene, o.device, s, "relight " + name);
    const auto renders = render_views(s, views, options, dir, true, "relight " + name, nullptr, nullptr, gpu);
    io::Json entry = io::Json::object();
    if (is_truth) {
      entry = compare_with_truth(renders, &renders, dir, o.sheet_rows);
      add_metrics(entry);
    } else if (truth) {
      apply_environment(*truth, envs[e]);
      GpuViewTracer* truth_gpu = gpu ? gpu_tracer_kept(gpu_truth, o.device, *truth, "relight " + name) : nullptr;
      const auto reference = render_views(*truth, views, options, dir / "reference", true,
                                          "relight " + name + " reference", nullptr, nullptr, truth_gpu);
      entry = compare_with_truth(renders, &reference, dir, o.sheet_rows);
      add_metrics(entry);
    }
    entry["environment"] = envs[e].spec;
    entry["environment_kind"] = envs[e].description();
    entry["folder"] = name;
    entry["device"] = gpu ? "cuda" : "cpu";
    per_env.push_back(entry);
  }
  if ((truth || is_truth) && !envs.empty()) {
    result["psnr"] = sum_psnr / double(envs.size());
    // the mean over the environments that have one; null (NaN) when none has
    result["psnr_mask"] = n_mask ? sum_mask / double(n_mask) : std::nan("");
    result["ssim"] = sum_ssim / double(envs.size());
  }
  result["views_per_environment"] = views.size();
  result["environments"] = per_env;
  result["out"] = out.final_path().string();
  io::write_json(out.path() / "relight.json", result);
  out.commit();
  emit_json(result, std::nullopt);
}

}  // namespace

void add_relight(CLI::App& app) {
  auto o = std::make_shared<RelightOptions>();
  CLI::App* cmd = app.add_subcommand("relight", "Render an object under other environment maps, against the ground truth");
  cmd->footer(
      "Renders the mesh + material from up to --views test views of --scene under each environment, and the\n"
      "scene's ground truth (gt/mesh.obj, gt/material.json) under the same one as the reference.\n"
      "Writes OUT/ENV/{images,previews,masks}/, OUT/ENV/reference/, OUT/ENV/metrics.json,\n"
      "OUT/ENV/contact_sheet.png (ground truth | render | error) and OUT/relight.json (means over maps).\n"
      "Example: difftrans relight --mesh S/gt/mesh.obj --material S/gt/material.json --scene S --all-envs --out out/relight");
  cmd->add_option("--mesh", o->mesh, "mesh (.obj or .ply), in the scene's frame")->required();
  o->material.add(cmd);
  cmd->add_option("--env", o->envs, "environment(s): map (.hdr/.exr), constant:R,G,B, radiance field (.json) or a reconstruct "
                                     "output folder");
  cmd->add_flag("--all-envs", o->all_envs, "every shared environment map except the scene's training one");
  cmd->add_option("--scene", o->scene, "scene directory (its test cameras and gt/)")->required();
  cmd->add_option("--views", o->views, "test views per environment")->capture_default_str()->check(CLI::Range(1, 100000));
  cmd->add_option("--max-depth", o->max_depth, "surface interactions per path")->capture_default_str()
      ->check(CLI::Range(1, render::max_trace_depth));
  cmd->add_option("--spp-axis", o->spp_axis, "n: n x n samples per pixel")->capture_default_str()->check(CLI::Range(1, 64));
  cmd->add_option("--sheet-rows", o->sheet_rows, "views in each contact sheet")->capture_default_str()->check(CLI::Range(1, 64));
  cmd->add_option("--data", o->data,
                  "data folder with envmaps/ (default: $DIFFTRANS_DATA, else the data/ folder of the "
                  "difftrans sources or installation)");
  cmd->add_option("--device", o->device, device_help)->capture_default_str()->check(CLI::IsMember({"cpu", "cuda", "auto"}));
  cmd->add_option("--out", o->out, "output folder")->required();
  cmd->add_flag("--overwrite", o->overwrite, "replace an existing, non-empty --out");
  cmd->callback([o] { run(*o); });
}

}  // namespace difftrans::cli
