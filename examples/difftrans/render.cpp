// difftrans render: a mesh with a material under an environment, seen from the
// cameras of a scene directory (or from generated protocol views); linear and
// tone-mapped images, masks, and — where the scene has images for those views —
// metrics (JSON) and a contact sheet (ground truth | render | error).
#include "output_folder.hpp"
#include "views.hpp"

namespace difftrans::cli {
namespace {

struct RenderOptions {
  std::string mesh, env, scene, split = "test", out, device = "cpu";
  MaterialOptions material;
  std::optional<int> views;
  std::string placement = "sphere";
  int resolution = 256;
  std::uint64_t seed = 0;
  int max_depth = 16, spp_axis = 4, sheet_rows = 4;
  float roulette = 0.0f;  // Russian roulette below this throughput (0: the whole tree)
  bool footprints = false;  // each sample reads the map over its stratum's footprint (render/footprint.hpp)
  float footprint_angle = render::FootprintSettings{}.max_angle;
  bool overwrite = false;
};

void run(const RenderOptions& o) {
  if (o.footprints && o.device == "cuda") throw std::runtime_error("--device cuda: --footprints is traced on the host only");
  check_device(o.device);
  if (o.scene.empty() == !o.views) throw CLI::ValidationError("give either --scene (its cameras) or --views N (protocol views)");
  const io::Material material = o.material.resolve();
  const io::Mesh mesh = load_mesh(o.mesh);
  const Environment env = load_environment(o.env);

  std::vector<View> views;
  bool with_truth = false;
  if (o.views) {
    const auto dirs = io::fibonacci_directions(*o.views, o.placement == "sphere" ? io::ViewSphere::sphere
                                                                               : io::ViewSphere::upper_hemisphere,
                                               io::view_offsets(o.seed).test);
    for (int i = 0; i < *o.views; ++i) {
      char name[64];
      std::snprintf(name, sizeof(name), "view_%03d", i);
      views.push_back(protocol_view(name, dirs[size_t(i)], o.resolution, o.resolution));
    }
  } else {
    io::LoadOptions lo;
    lo.read_pixels = false;
    const io::Scene scene = io::load_scene(o.scene, lo);
    for (const auto& w : scene.warnings) warn(w);
    const io::Split& split = o.split == "train" ? scene.train : scene.test;
    if (split.frames.empty()) throw io::Error(o.scene, "the scene has no " + o.split + " views");
    with_truth = true;
    for (const auto& f : split.frames) {
      if (f.environment_only) continue;
      views.push_back(view_from_frame(f));
    }
  }

  OutputDir out(o.out, o.overwrite, {o.mesh, o.scene, o.env, o.material.material_file, o.material.absorption_grid});
  render::HostScene s = render::make_host_scene(mesh, material, fs::path(o.mesh).filename().string());
  apply_environment(s, env);
  render::PassOptions pass = render::reference_pass_options(o.max_depth, o.spp_axis);
  if (o.roulette > 0.0f) {
    pass.trace.prune_throughput = o.roulette;
    pass.trace.roulette = true;
  }
  render::FootprintSettings footprints;
  footprints.max_angle = o.footprint_angle;
  // footprints filter an equirectangular map only (render/footprint.hpp)
  const bool use_footprints = o.footprints && !s.near_field && s.environment_width > 0;
  if (o.footprints && !use_footprints)
    warn("--footprints: the environment (" + env.description() +
         ") is not an equirectangular map; every sample reads it at one point");
  if (use_footprints && o.device == "auto") progress("render: tracing on the host (--footprints is traced on the host only)");
  const std::unique_ptr<GpuViewTracer> gpu = use_footprints ? nullptr : gpu_tracer_for(o.device, s, "render");
  RenderTotals totals;
  const auto rendered = render_views(s, views, pass, out.path(), true, "render", nullptr, &totals, gpu.get(),
                                     use_footprints ? &footprints : nullptr);
  io::write_transforms(out.path() / "transforms.json", split_of(rendered));
  io::Json result = io::Json::object();
  if (with_truth) {
    progress("render: comparing with " + o.scene);
    result = compare_with_truth(rendered, nullptr, out.path(), o.sheet_rows);
  }
  result["environment"] = env.description();
  result["views"] = rendered.size();
  result["trace"] = totals.json(rendered.size());
  result["device"] = gpu ? "cuda" : "cpu";
  result["footprints"] = use_footprints ? io::Json{{"max_angle", o.footprint_angle}} : io::Json(nullptr);
  result["out"] = out.final_path().string();
  io::write_json(out.path() / "render.json", result);
  out.commit();
  emit_json(result, std::nullopt);
}

}  // namespace

void add_render(CLI::App& app) {
  auto o = std::make_shared<RenderOptions>();
  CLI::App* cmd = app.add_subcommand("render", "Render a mesh + material + environment from a scene's cameras");
  cmd->footer(
      "Writes OUT/images/NAME.exr (linear), OUT/previews/NAME.png, OUT/masks/NAME.png (the rendered mesh's),\n"
      "OUT/transforms.json; with --scene also OUT/metrics.json (psnr, psnr_mask, ssim against the scene's images\n"
      "and masks) and OUT/contact_sheet.png (rows: ground truth | render | error heat map). The mesh is used as\n"
      "given (scenes from synth are in the normalized frame of gt/mesh.obj).\n"
      "Example: difftrans render --mesh S/gt/mesh.obj --material S/gt/material.json --env S/gt/envmap.hdr \\\n"
      "           --scene S --split test --out out/render");
  cmd->add_option("--mesh", o->mesh, "mesh (.obj or .ply)")->required();
  o->material.add(cmd);
  cmd->add_option("--env", o->env, "environment: equirectangular map (.hdr/.exr), constant:R,G,B, a radiance field (.json) or "
                                    "a reconstruct output folder (its field or map)")
      ->required();
  cmd->add_option("--scene", o->scene, "scene directory whose cameras (and images) to use");
  cmd->add_option("--split", o->split, "which views of --scene")->capture_default_str()->check(CLI::IsMember({"train", "test"}));
  cmd->add_option("--views", o->views, "instead of --scene: N protocol views (Fibonacci, radius 3, FoV 40)")
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--placement", o->placement, "--views on the sphere or the upper hemisphere")
      ->capture_default_str()->check(CLI::IsMember({"sphere", "hemisphere"}));
  cmd->add_option("--resolution", o->resolution, "--views image size")->capture_default_str()->check(CLI::Range(1, 16384));
  cmd->add_option("--seed", o->seed, "--views lattice turn")->capture_default_str();
  cmd->add_option("--max-depth", o->max_depth, "surface interactions per path")->capture_default_str()
      ->check(CLI::Range(1, render::max_trace_depth));
  cmd->add_option("--spp-axis", o->spp_axis, "n: n x n samples per pixel")->capture_default_str()->check(CLI::Range(1, 64));
  cmd->add_option("--roulette", o->roulette,
                  "Russian roulette below this branch throughput: unbiased, and at 0.01 about 3x faster at equal "
                  "quality on spot-clear (bench/equal_quality); 0: the whole Fresnel tree, as the reference renders")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_flag("--footprints", o->footprints,
               "each sample reads the environment averaged over its stratum's footprint (ray differentials): "
               "glints of a small sun spread over the pixels that see them; about 2x the time per sample, +0.3 to "
               "2.4 dB at equal samples on spot-clear (docs/metrics.md, Footprints); host only");
  cmd->add_option("--footprint-angle", o->footprint_angle,
                  "--footprints: the longest footprint edge, in radians (longer ones are shortened to it)")
      ->capture_default_str()
      ->check(CLI::Range(0.001, 3.15));
  cmd->add_option("--sheet-rows", o->sheet_rows, "views in the contact sheet")->capture_default_str()->check(CLI::Range(1, 64));
  cmd->add_option("--device", o->device, device_help)->capture_default_str()->check(CLI::IsMember({"cpu", "cuda", "auto"}));
  cmd->add_option("--out", o->out, "output folder")->required();
  cmd->add_flag("--overwrite", o->overwrite, "replace an existing, non-empty --out");
  cmd->callback([o] { run(*o); });
}

}  // namespace difftrans::cli
