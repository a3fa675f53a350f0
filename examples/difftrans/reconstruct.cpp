// difftrans reconstruct: the DiffTrans pipeline on a scene directory, stage
// by stage. Implemented so far: --stages environment (the distant map fitted
// to the out-of-mask pixels) and geometry (stage 1, stage_geometry.cpp).
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
  int env_width = 0;  // 0: from the images' angular resolution (capped)
  int env_max_width = 512;
  double smoothness = 1e-3;
  int margin = 2;
  bool overwrite = false;
};

double peak_memory_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

// The environment stage: fit, write envmap.hdr, a comparison sheet, metrics.
io::Json environment_stage(const io::Scene& scene, const ReconstructOptions& opt) {
  using clock = std::chrono::steady_clock;
  const std::string kind = scene.has_scene_json ? io::to_string(scene.settings.environment) : "distant";
  if (!scene.has_scene_json)
    progress("environment: scene.json absent, so the environment is taken as distant (an equirectangular map)");
  if (kind == "near")
    throw std::runtime_error(scene.dir.string() + "/scene.json: environment \"near\" asks for a near-field radiance "
                             "field, which this version cannot fit yet; remove the key to fit a distant map");
  const auto t0 = clock::now();
  std::vector<std::string> skipped;
  render::BackgroundOptions bo;
  bo.margin = opt.margin;
  const auto obs = render::background_observations(scene.train, bo, &skipped);
  for (const auto& name : skipped) warn("environment: frame " + name + " has no mask; its pixels are not used");
  scene::EnvFitOptions fo;
  if (opt.env_width > 0) {
    fo.width = opt.env_width;
  } else {
    const auto& k = scene.train.frames.front().intrinsics;
    fo.width = scene::envmap_width_for(1.0 / std::max(k.fx, k.fy), opt.env_max_width);
  }
  fo.height = fo.width / 2;
  fo.smoothness = opt.smoothness;
  progress("environment: fitting a " + std::to_string(fo.width) + " x " + std::to_string(fo.height) + " map to " +
           std::to_string(obs.size()) + " background pixels");
  const scene::EnvFit fit = scene::fit_environment(obs, fo);
  const double fit_seconds = std::chrono::duration<double>(clock::now() - t0).count();
  io::Image map(fit.width, fit.height);
  map.rgb = fit.texels;
  for (float& v : map.rgb) v = std::max(v, 0.0f);  // radiance: the least-squares fit may ring slightly negative
  io::write_hdr(opt.out / "envmap.hdr", map);
  const scene::EnvMap env = scene::equirect_environment(map.rgb.data(), map.width, map.height);

  io::Json j;
  j["model"] = "distant";
  j["width"] = fit.width;
  j["height"] = fit.height;
  j["observations"] = fit.observations;
  j["seen_fraction"] = fit.seen_fraction;
  j["rms_residual"] = fit.rms_residual;
  j["fit_seconds"] = fit_seconds;
  j["peak_memory_mb"] = peak_memory_mb();
  j["psnr_background_train"] = render::background_psnr(scene.train, env, opt.margin);
  if (!scene.test.frames.empty()) j["psnr_background_test"] = render::background_psnr(scene.test, env, opt.margin);
  // against the ground-truth map, over the directions the cameras saw
  if (!scene.gt.envmap.empty() && fs::exists(scene.gt.envmap)) {
    const io::Image gt = io::read_image(scene.gt.envmap);
    const scene::EnvMap gt_env = scene::equirect_environment(gt.rgb.data(), gt.width, gt.height);
    ad::ParamReader<float> reader(nullptr);
    double se = 0;
    std::int64_t n = 0;
    for (int r = 0; r < fit.height; ++r)
      for (int c = 0; c < fit.width; ++c) {
        if (!fit.seen[std::size_t(r) * fit.width + c]) continue;
        const Vec3f d = scene::uv_to_direction((c + 0.5f) / fit.width, (r + 0.5f) / fit.height);
        const Vec3f want = scene::lookup(reader, gt_env, d), got = map.at(c, r);
        for (int k = 0; k < 3; ++k) {
          const double e = double(io::tone_map_value(got[k])) - double(io::tone_map_value(want[k]));
          se += e * e;
          ++n;
        }
      }
    if (n) j["psnr_map_seen"] = metrics::detail::psnr_from_mse(se / double(n));
  }
  // pictures: background pixels against the fitted environment, a few views
  const io::Split& views = scene.test.frames.empty() ? scene.train : scene.test;
  std::vector<io::Image> renders;
  std::vector<io::SheetRow> rows;
  const auto picked = io::spread_indices(int(views.frames.size()), 4);
  renders.reserve(picked.size());
  for (int i : picked) renders.push_back(render::environment_view(views.frames[std::size_t(i)], env));
  for (std::size_t k = 0; k < picked.size(); ++k) rows.push_back({&views.frames[std::size_t(picked[k])].image, &renders[k]});
  if (!rows.empty()) io::write_png8(opt.out / "environment_comparison.png", io::comparison_sheet(rows));
  return j;
}

}  // namespace

void add_reconstruct(CLI::App& app) {
  auto opt = std::make_shared<ReconstructOptions>();
  auto geometry = std::make_shared<GeometryStageOptions>();
  CLI::App* cmd = app.add_subcommand("reconstruct", "Reconstruct a transparent object from a scene directory");
  cmd->add_option("scene", opt->scene, "Scene directory (transforms_train.json, images, masks)")->required();
  cmd->add_option("--out", opt->out, "Output directory")->required();
  cmd->add_option("--stages", opt->stages, "Stages to run, comma-separated: environment, geometry")->capture_default_str();
  cmd->add_option("--env-width", opt->env_width, "Environment map width (0: from the images' angular resolution)");
  cmd->add_option("--env-max-width", opt->env_max_width, "Largest automatic map width")->capture_default_str();
  cmd->add_option("--env-smoothness", opt->smoothness, "Weight of the environment's smoothness prior")->capture_default_str();
  cmd->add_option("--margin", opt->margin, "Pixels around the mask left out of the environment fit")->capture_default_str();
  add_geometry_options(cmd, *geometry);
  cmd->callback([opt, geometry] {
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
        result["environment"] = environment_stage(scene, *opt);
      } else if (s == "geometry") {
        result["geometry"] = geometry_stage(scene, opt->out, *geometry);
      }
    emit_json(result, opt->out / "reconstruct.json");
  });
}

}  // namespace difftrans::cli
