// difftrans reconstruct --stages environment: the environment from the
// background (out-of-mask) pixels of the training views. Two models, chosen
// from those pixels (choose_environment; scene.json's "environment" decides a
// tie) or forced with --env-model:
//   distant  an equirectangular map, sparse least squares (scene/envmap_fit.hpp);
//   near     a radiance field (density + colour voxel grid) trained by volume
//            rendering (scene/radiance_field_fit.hpp), for backgrounds at
//            finite distance where parallax matters.
// Both write DIR/envmap.hdr (for the field: its panorama seen from the
// object's centre), DIR/environment_comparison.png (image | re-rendered
// background | error) and their record in reconstruct.json.
#include <chrono>
#include <cstdint>
#include <exception>
#include <limits>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>
#include <sys/resource.h>

#include "command.hpp"
#include "config_options.hpp"
#include "stages.hpp"
#include "stage_output.hpp"
#include "views.hpp"

#include "difftrans/io/contact_sheet.hpp"
#include "difftrans/io/hdr.hpp"
#include "difftrans/io/png.hpp"
#include "difftrans/io/radiance_field.hpp"
#include "pipeline/environment.hpp"
#include "pipeline/model_choice.hpp"
#include "difftrans/scene/radiance_field_fit.hpp"

namespace difftrans::cli {
namespace {

using clock_type = std::chrono::steady_clock;

// "32,64,128": positive integers, each >= min, or a ValidationError naming the option.
std::vector<int> parse_int_list(const std::string& text, const std::string& option, int min) {
  std::vector<int> out;
  std::stringstream ss(text);
  for (std::string part; std::getline(ss, part, ',');) {
    char* end = nullptr;
    const long v = std::strtol(part.c_str(), &end, 10);
    if (part.empty() || *end != '\0' || v < min || v > 100000)
      throw CLI::ValidationError(option, "'" + text + "' is not a comma-separated list of integers >= " +
                                             std::to_string(min));
    out.push_back(int(v));
  }
  if (out.empty()) throw CLI::ValidationError(option, "is empty");
  return out;
}

// The map width: --env-width, else from the images' angular resolution.
int map_width(const io::Scene& scene, const pipeline::EnvironmentConfig& opt) {
  if (opt.env_width > 0) return opt.env_width;
  const auto& k = scene.train.frames.front().intrinsics;
  return scene::envmap_width_for(1.0 / std::max(k.fx, k.fy), opt.env_max_width);
}

// A comparison sheet of up to 4 views: image | environment re-rendered | error.
template <class Radiance>
void write_comparison(const io::Scene& scene, const Radiance& radiance, const fs::path& file) {
  const io::Split& views = scene.test.frames.empty() ? scene.train : scene.test;
  std::vector<io::Image> renders;
  std::vector<io::SheetRow> rows;
  const auto picked = io::spread_indices(int(views.frames.size()), 4);
  renders.reserve(picked.size());
  for (int i : picked) renders.push_back(pipeline::environment_view_with(views.frames[std::size_t(i)], radiance));
  for (std::size_t k = 0; k < picked.size(); ++k)
    rows.push_back({&views.frames[std::size_t(picked[k])].image, &renders[k]});
  if (!rows.empty()) io::write_png8(file, io::comparison_sheet(rows));
}

std::vector<scene::EnvObservation> observations(const io::Scene& scene, const pipeline::EnvironmentConfig& opt) {
  std::vector<std::string> skipped;
  pipeline::BackgroundOptions bo;
  bo.margin = opt.margin;
  auto obs = pipeline::background_observations(scene.train, bo, &skipped);
  for (const auto& name : skipped) warn("environment: frame " + name + " has no mask; its pixels are not used");
  if (obs.empty())
    throw io::Error(scene.dir, "no background pixels to fit the environment to (every training pixel lies within " +
                                   std::to_string(opt.margin) + " pixels of the mask, or no frame has a mask)");
  return obs;
}

scene::EnvFitOptions distant_fit_options(const io::Scene& scene, const pipeline::EnvironmentConfig& opt) {
  scene::EnvFitOptions fo;
  fo.width = map_width(scene, opt);
  fo.height = fo.width / 2;
  fo.smoothness = opt.smoothness;
  return fo;
}

// Distant: the equirectangular map.
io::Json distant_environment(const io::Scene& scene, const fs::path& out, const pipeline::EnvironmentConfig& opt) {
  const auto t0 = clock_type::now();
  const auto obs = observations(scene, opt);
  const scene::EnvFitOptions fo = distant_fit_options(scene, opt);
  progress("environment: fitting a " + std::to_string(fo.width) + " x " + std::to_string(fo.height) + " map to " +
           std::to_string(obs.size()) + " background pixels");
  const scene::EnvFit fit = scene::fit_environment(obs, fo);
  const double fit_seconds = std::chrono::duration<double>(clock_type::now() - t0).count();
  io::Image map(fit.width, fit.height);
  map.rgb = fit.texels;
  for (float& v : map.rgb) v = std::max(v, 0.0f);  // radiance: the least-squares fit may ring slightly negative
  io::write_hdr(out / "envmap.hdr", map);
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
  j["psnr_background_train"] = pipeline::background_psnr(scene.train, env, opt.margin);
  if (!scene.test.frames.empty()) j["psnr_background_test"] = pipeline::background_psnr(scene.test, env, opt.margin);
  // against the ground-truth map, over the directions the cameras saw
  // (a report: a failure is a warning, the stage's results stand)
  if (!scene.gt.envmap.empty() && fs::exists(scene.gt.envmap)) {
    try {
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
    } catch (const std::exception& e) {
      warn(std::string("environment: no comparison with the ground truth: ") + e.what());
      j["ground_truth_error"] = e.what();
    }
  }
  write_comparison(scene, pipeline::distant_radiance(env), out / "environment_comparison.png");
  return j;
}

// The near field's cube: around the object's centre (scene.json's box, else
// the origin), field_extent times the farthest training camera's distance.
struct NearBox {
  Vec3f centre{0.0f}, lo{0.0f}, hi{0.0f};
  float half = 0.0f;
};
NearBox near_box(const io::Scene& scene, const pipeline::EnvironmentConfig& opt) {
  NearBox b;
  if (scene.settings.aabb) b.centre = Vec3f((scene.settings.aabb->lo + scene.settings.aabb->hi) * 0.5);
  float reach = 0.0f;
  for (const io::Frame& f : scene.train.frames)
    reach = std::max(reach, glm::length(Vec3f(Vec3d(f.camera_to_world[3])) - b.centre));
  if (!(reach > 1e-6f))
    throw io::Error(scene.dir, "the training cameras sit at the object's centre: no box for a radiance field");
  b.half = opt.field_extent * reach;
  b.lo = b.centre - Vec3f(b.half);
  b.hi = b.centre + Vec3f(b.half);
  return b;
}

// The field fit's options; for_choice: the iterations of the model choice's field.
scene::FieldFitOptions near_fit_options(const pipeline::EnvironmentConfig& opt, bool for_choice = false) {
  scene::FieldFitOptions fo;
  fo.resolutions = parse_int_list(opt.field_resolutions, "--field-resolutions", 2);
  const char* flag = for_choice ? "--env-choice-iterations" : "--field-iterations";
  fo.iterations = parse_int_list(for_choice ? opt.choice_field_iterations : opt.field_iterations, flag, 0);
  if (fo.iterations.size() != 1 && fo.iterations.size() != fo.resolutions.size())
    throw CLI::ValidationError(flag, "give one count, or one per level of --field-resolutions (" +
                                         std::to_string(fo.resolutions.size()) + ")");
  fo.batch = opt.field_batch;
  fo.lr = opt.field_lr;
  fo.lr_final = opt.field_lr * 0.1f;
  fo.smoothness_density = fo.smoothness_colour = opt.field_tv;
  fo.sparsity = opt.field_sparsity;
  fo.seed = opt.field_seed;
  return fo;
}

// Near: the radiance field in a cube around the object's centre that holds every training camera.
io::Json near_environment(const io::Scene& scene, const fs::path& out, const pipeline::EnvironmentConfig& opt) {
  const scene::FieldFitOptions fo = near_fit_options(opt);

  const auto t0 = clock_type::now();
  const auto obs = observations(scene, opt);
  const NearBox box = near_box(scene, opt);
  const Vec3f centre = box.centre, lo = box.lo, hi = box.hi;
  progress("environment: fitting a radiance field (" + opt.field_resolutions + " vertices per axis, " +
           opt.field_iterations + " iterations, " + std::to_string(fo.batch) + " rays each) in a cube of half-size " +
           fixed(box.half, 2) + " around the object to " + std::to_string(obs.size()) + " background pixels");
  scene::FieldFitReport report;
  const scene::RadianceField field = scene::fit_radiance_field(
      obs, lo, hi, fo, &report, [&](int level, int it, double mse) {
        progress("environment: level " + std::to_string(level) + " (" +
                 std::to_string(fo.resolutions[std::size_t(level)]) + "^3) it " + std::to_string(it) + ": mse " +
                 fixed(mse, 5) + ", " + fixed(std::chrono::duration<double>(clock_type::now() - t0).count(), 1) + " s");
      });
  const double fit_seconds = std::chrono::duration<double>(clock_type::now() - t0).count();
  io::write_radiance_field(out / "radiance_field.json", field, fo.occupancy_sigma);
  const scene::FieldRadiance radiance{field.view()};

  // the panorama seen from the object's centre
  const int w = map_width(scene, opt), h = w / 2;
  io::Image pano(w, h);
  parallel_for(h, 1, [&](std::int64_t r0, std::int64_t r1, int) {
    for (int r = int(r0); r < int(r1); ++r)
      for (int c = 0; c < w; ++c)
        pano.set(c, r, radiance(centre, scene::uv_to_direction((c + 0.5f) / float(w), (r + 0.5f) / float(h))));
  });
  io::write_hdr(out / "envmap.hdr", pano);

  io::Json j;
  j["model"] = "near";
  j["resolution"] = fo.resolutions.back();
  j["levels"] = fo.resolutions;
  j["iterations"] = report.iterations;
  j["batch"] = fo.batch;
  j["box"] = {{"lo", {lo.x, lo.y, lo.z}}, {"hi", {hi.x, hi.y, hi.z}}};
  j["observations"] = obs.size();
  j["occupied_fraction"] = report.occupied_fraction;
  j["last_batch_mse"] = report.last_mse;
  j["field"] = "radiance_field.json";
  j["panorama"] = {{"width", w}, {"height", h}, {"from", {centre.x, centre.y, centre.z}}};
  j["fit_seconds"] = fit_seconds;
  j["peak_memory_mb"] = peak_memory_mb();
  j["psnr_background_train"] = pipeline::background_psnr_with(scene.train, radiance, opt.margin);
  if (!scene.test.frames.empty())
    j["psnr_background_test"] = pipeline::background_psnr_with(scene.test, radiance, opt.margin);
  write_comparison(scene, radiance, out / "environment_comparison.png");
  return j;
}

// auto: the model from the background pixels themselves. Both models are
// fitted to the training frames less every choice_holdout-th and scored on
// the held-out frames' background pixels (tone-mapped squared error per
// pixel, paired: model_choice.hpp). A distant map cannot show parallax, so in
// a room its held-out error stays high where the near field's falls; under a
// far map the near field gains nothing. The near field is kept when it wins
// measurably; when neither does, scene.json's entry (the hint) decides, and
// without one the distant map, the cheaper model.
std::pair<std::string, io::Json> choose_environment(const io::Scene& scene, const pipeline::EnvironmentConfig& opt,
                                                    const std::string& hint) {
  const auto t0 = clock_type::now();
  const int every = std::max(2, opt.choice_holdout);
  io::Split train, held;
  for (std::size_t i = 0; i < scene.train.frames.size(); ++i)
    (int(i) % every == every / 2 ? held : train).frames.push_back(scene.train.frames[i]);
  io::Json r = {{"requested", "auto"}, {"hint", hint.empty() ? io::Json() : io::Json(hint)}, {"holdout_every", every},
                {"heldout_views", held.frames.size()}};
  const std::string fallback = hint.empty() ? "distant" : hint;
  pipeline::BackgroundOptions bo;
  bo.margin = opt.margin;
  const auto obs = pipeline::background_observations(train, bo);
  const std::size_t held_pixels = pipeline::background_observations(held, bo).size();
  if (obs.empty() || held_pixels < 2) {
    r["decision"] = fallback;
    r["reason"] = "too few views or background pixels to hold some out";
    return {fallback, r};
  }
  progress("environment: choosing the model: a distant map and a near field fitted without every " +
           std::to_string(every) + "th view, compared on the " + std::to_string(held.frames.size()) +
           " held out (" + std::to_string(held_pixels) + " background pixels)");
  // distant
  auto t = clock_type::now();
  const scene::EnvFit fit = scene::fit_environment(obs, distant_fit_options(scene, opt));
  std::vector<float> texels = fit.texels;
  for (float& v : texels) v = std::max(v, 0.0f);
  const scene::EnvMap env = scene::equirect_environment(texels.data(), fit.width, fit.height);
  std::vector<double> distant;
  std::vector<Vec3f> directions;
  for (const io::Frame& f : held.frames)
    pipeline::background_errors_with(f, pipeline::distant_radiance(env), opt.margin, distant, &directions);
  const double distant_seconds = std::chrono::duration<double>(clock_type::now() - t).count();
  // near
  t = clock_type::now();
  const NearBox box = near_box(scene, opt);
  const scene::RadianceField field = scene::fit_radiance_field(obs, box.lo, box.hi, near_fit_options(opt, true));
  const scene::FieldRadiance radiance{field.view()};
  std::vector<double> near;
  for (const io::Frame& f : held.frames) pipeline::background_errors_with(f, radiance, opt.margin, near);
  const double near_seconds = std::chrono::duration<double>(clock_type::now() - t).count();

  // Only held-out pixels whose direction the training views' background saw
  // (every texel of its bilinear look-up): elsewhere the map is its prior's
  // fill and the field its guess, and with few views a held-out view sees
  // much that no other did (on the tests' 16² scene under a distant map the
  // distant map lost to the near field there, 7.5 dB against 11.6 dB).
  // Where both saw, what a distant map cannot explain is parallax.
  const std::vector<std::uint8_t> seen = pipeline::seen_texels(obs, fit.width, fit.height);
  std::size_t unseen = 0;
  for (std::size_t i = 0; i < directions.size() && i < near.size(); ++i) {
    const scene::Footprint<float> fp =
        scene::bilinear_footprint(fit.width, fit.height, scene::direction_to_uv(directions[i]));
    bool all = fp.valid;
    for (int k = 0; k < 4 && all; ++k) all = !(fp.weight[k] > 0.0f) || seen[std::size_t(fp.texel[k])];
    if (!all) {
      distant[i] = near[i] = std::numeric_limits<double>::quiet_NaN();
      ++unseen;
    }
  }
  r["unseen_pixels"] = unseen;
  const pipeline::PairedComparison c = pipeline::compare_paired(distant, near);
  const bool near_wins = c.richer_wins(2.0, opt.choice_min_gain);
  const bool distant_wins = pipeline::compare_paired(near, distant).richer_wins(2.0, opt.choice_min_gain);
  const std::string model = near_wins ? "near" : distant_wins ? "distant" : fallback;
  const auto psnr = [](double mean_error) { return metrics::detail::psnr_from_mse(mean_error / 3.0); };
  const double rel = c.simpler > 0.0 ? c.gain / c.simpler : 0.0, rel_se = c.simpler > 0.0 ? c.standard_error / c.simpler : 0.0;
  r["distant"] = {{"heldout_error", c.simpler}, {"heldout_psnr", psnr(c.simpler)}, {"fit_seconds", distant_seconds}};
  r["near"] = {{"heldout_error", c.richer}, {"heldout_psnr", psnr(c.richer)}, {"fit_seconds", near_seconds}};
  r["pixels"] = c.pixels;
  r["gain"] = c.gain;
  r["standard_error"] = c.standard_error;
  r["relative_gain"] = rel;
  r["rule"] = "near when it lowers the held-out error by more than 2 standard errors and by more than " +
              fixed(100.0 * opt.choice_min_gain, 1) + " %; distant when it does so against the near field; else the hint";
  r["decision"] = model;
  r["reason"] = near_wins ? "the near field is measurably better"
                : distant_wins ? "the distant map is measurably better"
                               : (hint.empty() ? "neither is measurably better: the distant map, the cheaper"
                                               : "neither is measurably better: scene.json's \"" + hint + "\"");
  r["seconds"] = std::chrono::duration<double>(clock_type::now() - t0).count();
  progress("environment: " + model + " (" + std::to_string(c.pixels) +
           " held-out background pixels in directions the others saw; PSNR: distant " + fixed(psnr(c.simpler), 2) + " dB, near " +
           fixed(psnr(c.richer), 2) + " dB; the near field's error " + (rel >= 0.0 ? "-" : "+") +
           fixed(std::abs(100.0 * rel), 2) + " % ± " + fixed(100.0 * rel_se, 2) + " %: " +
           r["reason"].get<std::string>() + "), in " + duration_text(r["seconds"].get<double>()));
  return {model, r};
}

}  // namespace

void add_environment_options(CLI::App* cmd, pipeline::EnvironmentConfig& config) {
  add_config_options(cmd, config, "");
}

io::Json environment_stage(const io::Scene& scene, const fs::path& out, const pipeline::EnvironmentConfig& opt) {
  const std::string requested = pipeline::detail::enum_name(opt.model);
  std::string model = requested;
  io::Json choice;
  if (scene.train.frames.empty()) throw io::Error(scene.dir, "no training frames");
  if (opt.model == pipeline::EnvironmentModel::automatic) {
    const std::string hint = scene.has_scene_json ? io::to_string(scene.settings.environment) : std::string();
    std::tie(model, choice) = choose_environment(scene, opt, hint);
  } else if (scene.has_scene_json && model != io::to_string(scene.settings.environment)) {
    progress("environment: --env-model " + model + " overrides scene.json's \"" +
             io::to_string(scene.settings.environment) + "\"");
  }
  io::Json j = model == "near" ? near_environment(scene, out, opt) : distant_environment(scene, out, opt);
  pipeline::write_fields(opt, j["settings"]);
  j["model_source"] = opt.model == pipeline::EnvironmentModel::automatic ? "background pixels" : "--env-model";
  if (!choice.is_null()) j["choice"] = choice;
  progress("environment: " + model + " model, background PSNR train " + fixed(j["psnr_background_train"].get<double>(), 2) +
           (j.contains("psnr_background_test") ? ", test " + fixed(j["psnr_background_test"].get<double>(), 2) : "") +
           " dB, " + fixed(j["fit_seconds"].get<double>(), 1) + " s");
  return j;
}

}  // namespace difftrans::cli
