// difftrans reconstruct --stages materials: stage 2. The stage-1 mesh
// (DIR/mesh_stage1.obj) and the recovered environment (DIR/envmap.hdr, or the
// near field DIR/radiance_field.json) are read back; the IoR and an
// absorption (none, homogeneous or a grid, chosen from held-out views unless
// --absorption names one; and the vertices, unless --materials-geometry=false)
// are fitted to the photographs' object pixels through the recursive tracer.
// Writes material_stage2.json (+ absorption_stage2.json for a grid),
// mesh_stage2.obj, the loss
// curve, renders of the test views with metrics and a contact sheet, and the
// IoR / CD / F1 errors when the scene has ground truth.
#include "long_run.hpp"
#include "materials_views.hpp"
#include "stages.hpp"
#include "stage_output.hpp"
#include "views.hpp"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>
#include <sys/resource.h>

#include "difftrans/io/contact_sheet.hpp"
#include "difftrans/io/hdr.hpp"
#include "difftrans/io/material.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/io/radiance_field.hpp"
#include "difftrans/metrics/absorption.hpp"
#include "difftrans/metrics/chamfer.hpp"
#include "difftrans/metrics/ior.hpp"
#include "difftrans/metrics/mesh_quality.hpp"
#include "difftrans/metrics/normals.hpp"
#include "difftrans/render/mesh_picture.hpp"
#include "config_options.hpp"
#include "pipeline/environment.hpp"
#include "pipeline/materials.hpp"

namespace difftrans::cli {

// The vertex phase against the true mesh, level by level: chamfer, F1 and
// the shading-normal error at its start and whenever the large-steps λ or
// the environment blur changes (the end of a level), and at its end. Inert
// without a readable true mesh. (The loss at each level, which needs no
// truth, is Stage2's: vertex_levels().)
class GeometryLevels {
 public:
  explicit GeometryLevels(const fs::path& truth) {
    if (truth.empty() || !fs::exists(truth)) return;
    try {
      truth_ = io::read_mesh(truth);
      active_ = true;
    } catch (const std::exception& e) {
      warn(std::string("materials: no level-by-level comparison with the true mesh: ") + e.what());
    }
  }
  void record(const io::Mesh& m, int iteration, const std::string& after) {
    if (!active_) return;
    const auto g = metrics::evaluate_geometry(m, truth_);
    const metrics::NormalError n = metrics::normal_error(m, truth_);
    io::Json e = {{"iteration", iteration}, {"after", after}, {"chamfer", g.chamfer}, {"f1", g.f1},
                  {"normal_error_deg", normal_error_json(n)}};
    progress("materials: vertices at iteration " + std::to_string(iteration) + " (" + after + "): CD " +
             fixed(g.chamfer, 7) + ", F1 " + fixed(g.f1, 4) + ", normals off by " + fixed(n.mean_deg, 2) +
             " deg on average");
    json_.push_back(std::move(e));
  }
  // After each moving step: a new λ or blur closes the level before it.
  void step(const pipeline::Stage2Stats& st, const scene::TriangleMesh& mesh) {
    if (!active_) return;
    if (started_ && (st.lambda != lambda_ || st.environment_blur != blur_))
      record(to_io_mesh(mesh.positions, mesh.triangles), st.iteration, label());
    started_ = true;
    lambda_ = st.lambda;
    blur_ = st.environment_blur;
  }
  void finish(const scene::TriangleMesh& mesh, int iteration) {
    if (active_ && started_) record(to_io_mesh(mesh.positions, mesh.triangles), iteration, label() + ", the end");
  }
  const io::Json& json() const { return json_; }

 private:
  std::string label() const { return "lambda " + fixed(lambda_, 2) + ", blur " + fixed(blur_, 2) + " texels"; }
  io::Mesh truth_;
  bool active_ = false, started_ = false;
  double lambda_ = 0.0;
  float blur_ = 0.0f;
  io::Json json_ = io::Json::array();
};

// Lattice points per axis over the true mesh's box for the absorption error
// (docs/metrics.md): about 48³ · (the object's share of its box) points.
constexpr int absorption_error_lattice = 48;

// The surface before and after the vertices moved, against the truth, as one
// picture: rows stage 1 and stage 2 (each vertex coloured by its distance to
// the true surface, io::heat_color: black at 0, pale yellow at tau and
// beyond) and the truth (grey); columns the six views of
// render::cameras_around the truth.
void write_geometry_picture(const std::filesystem::path& path, const io::Mesh& before, const io::Mesh& after,
                            const io::Mesh& truth) {
  const metrics::GeometryOptions options;
  const int size = 160;
  const std::vector<scene::Camera> cams = render::cameras_around(io::flat_positions(truth), size);
  std::vector<std::vector<io::Image8>> rows;
  for (const io::Mesh* m : {&before, &after, &truth}) {
    const std::vector<float> positions = io::flat_positions(*m);
    const std::vector<std::int32_t> triangles = io::flat_triangles(*m);
    std::vector<render::VertexColour> colours(m->positions.size(), render::VertexColour{170, 170, 170});
    if (m != &truth) {
      const std::vector<double> d = metrics::vertex_distances(*m, truth, options);
      for (std::size_t v = 0; v < d.size(); ++v) colours[v] = io::heat_color(float(d[v] / options.tau));
    }
    rows.emplace_back();
    for (const scene::Camera& cam : cams) rows.back().push_back(render::vertex_colour_picture(positions, triangles, colours, cam));
  }
  io::SheetLayout layout;
  layout.tile_width = layout.tile_height = size;
  layout.rows = int(rows.size());
  layout.cols = int(cams.size());
  io::write_png8(path, io::compose_sheet(layout, rows));
}

namespace {

// The progress line's absorption figure from reconstruct.json's
// absorption_error (docs/metrics.md): the mean relative error over the
// channels the truth absorbs in, and the mean absolute σ fitted in those it
// leaves clear (a clear object fitted an absorption has no relative error to
// show, yet is wrong).
std::string absorption_error_text(const io::Json& e) {
  std::string text, clear;
  bool absorbing = false, any_clear = false;
  for (std::size_t c = 0; c < 3; ++c) {
    const bool channel_clear = e["mean_true"][c].get<double>() <= 1e-6;
    absorbing = absorbing || !channel_clear;
    any_clear = any_clear || channel_clear;
    clear += (c ? " / " : "") + (channel_clear ? fixed(e["mean_absolute"][c].get<double>(), 3) : std::string("-"));
  }
  if (absorbing) text = ", absorption error " + fixed(100.0 * e["mean_relative"].get<double>(), 1) + " %";
  if (any_clear) text += ", absorption " + clear + " per unit length where the truth is clear";
  return text;
}

// Stage2::settle_ior's result: its record in reconstruct.json, and its log
// line (`from`: where its start came from).
io::Json settle_record(const pipeline::Stage2::IorSettle& settle) {
  io::Json ev = io::Json::array();
  for (const auto& e : settle.evaluations)
    ev.push_back({{"ior", e.ior}, {"mean_gradient", e.mean_gradient}, {"standard_error", e.standard_error}});
  io::Json r = {{"start", settle.start},
                {"ior", settle.ior},
                {"settled", settle.settled},
                {"slope", settle.slope},
                {"slope_standard_error", settle.slope_standard_error},
                {"evaluations", ev}};
  if (std::isfinite(settle.standard_error)) r["ior_standard_error"] = settle.standard_error;
  return r;
}
std::string settle_text(const pipeline::Stage2::IorSettle& settle, const std::string& from, int batches) {
  return "IoR " + fixed(settle.start, 4) + " (" + from + ") " +
         (settle.settled ? "settled at " + fixed(settle.ior, 4) + " ± " + fixed(settle.standard_error, 4) +
                               ", the zero of the IoR gradient's line over " + std::to_string(batches) +
                               " fixed batches"
                         : std::string(std::isfinite(settle.standard_error)
                                           ? "moved to the edge of the last IoRs tried: " + fixed(settle.ior, 4)
                                           : "kept: the IoR gradient shows no significant slope")) +
         " (" + std::to_string(settle.evaluations.size()) + " IoRs evaluated)";
}

// render::ray_group_gradient's meaning, traced by `gpu` (Stage2::set_batch_gradient).
// A group whose gradient the GPU could not hold on its longest tape counts
// as overflowed, as on the host.
inline pipeline::Stage2::BatchGradient gpu_batch_gradient(GpuBatchTracer& gpu) {
  return [&gpu](const render::HostScene& s, const std::vector<render::BatchRay>& rays, int group,
                const pipeline::Stage2::GroupLoss& loss, render::SceneGradient& grad, const render::PassOptions& po,
                float clip_geometry, float clip_ior) {
    std::vector<float> r6;
    r6.reserve(rays.size() * 6);
    for (const render::BatchRay& r : rays)
      for (const Vec3f& v : {r.origin, r.direction}) r6.insert(r6.end(), {v.x, v.y, v.z});
    const GpuBatchStats st = gpu.gradient(s, r6, group, loss, grad, po.trace, clip_geometry, clip_ior);
    render::RayBatchResult out;
    out.loss = st.loss;
    out.stats.rays = st.rays;
    out.stats.trace.segments = st.segments;
    out.stats.overflowed_rays = st.dropped_rays;
    out.stats.max_tape_nodes = st.max_tape_nodes;
    out.clipped_rays = st.clipped_geometry;
    out.clipped_ior_rays = st.clipped_ior;
    return out;
  };
}

}  // namespace

void add_materials_options(CLI::App* cmd, pipeline::Stage2Config& config) {
  add_config_options(cmd, config, "Materials: ");
  // --ior-init: a number, where the IoR starts (the scan off), or "scan"
  cmd->add_option_function<std::string>(
         "--ior-init",
         [&config](const std::string& value) {
           if (value == "scan") {
             config.ior_scan = true;
             return;
           }
           std::size_t used = 0;
           float x = 0.0f;
           try {
             x = std::stof(value, &used);
           } catch (const std::exception&) {
             used = 0;
           }
           if (used != value.size() || !(x >= 1.0f && x <= 3.0f))
             throw CLI::ValidationError("--ior-init", "'" + value + "' is neither an IoR in [1, 3] nor 'scan'");
           config.ior_init = x;
           config.ior_scan = false;
         },
         "Materials: where the IoR starts: scan (the lowest loss of a few fixed batches among --ior-scan-values, "
         "before the absorption is chosen, when it beats the loss at 1.5 by 2 standard errors and "
         "--ior-scan-min-gain; else 1.5: docs/model-choice.md), or a number (no scan)")
      ->default_str("scan");
}

io::Json materials_stage(const io::Scene& scene, RunFolder& folder, const pipeline::Stage2Config& config,
                         const RunOptions& run) {
  namespace fs = std::filesystem;
  using clock = std::chrono::steady_clock;
  const auto t_start = clock::now();
  const fs::path& out = folder.work();
  const fs::path mesh_path = config.mesh.empty() ? out / "mesh_stage1.obj" : fs::path(config.mesh);
  if (!fs::exists(mesh_path))
    throw std::runtime_error(folder.shown(mesh_path).string() + ": the stage-1 mesh is missing; run --stages geometry first "
                             "(or give --materials-mesh)");
  const io::Mesh mesh = io::read_mesh(mesh_path);
  render::HostScene s = render::make_host_scene(mesh, io::Material{}, mesh_path.filename().string());
  io::Json j;
  j["mesh_in"] = folder.shown(mesh_path).string();
  const metrics::MeshQuality quality_in = metrics::mesh_quality(s.mesh.positions, s.mesh.triangles);
  // what the fit starts from, to tell a checkpoint of this run from another's
  std::string inputs = "mesh " + fingerprint(mesh.positions) + fingerprint(mesh.triangles);
  // the environment recovered by the environment stage
  const fs::path field_path = out / "radiance_field.json", env_path = out / "envmap.hdr";
  if (fs::exists(field_path)) {
    auto field = std::make_shared<const scene::RadianceField>(io::read_radiance_field(field_path));
    inputs += " field " + fingerprint(field->values);
    s.set_near_field(std::move(field));
    j["environment"] = folder.shown(field_path).string();
  } else if (fs::exists(env_path)) {
    const io::Image map = io::read_image(env_path);
    inputs += " map " + fingerprint(map.rgb);
    render::set_environment(s, map);
    j["environment"] = folder.shown(env_path).string();
  } else {
    throw std::runtime_error(folder.shown(env_path).string() + ": no recovered environment; run --stages environment first");
  }

  // training views: images and masks
  MaterialsViews training = materials_training_views(scene);
  std::vector<pipeline::Stage2View>& views = training.views;
  std::vector<pipeline::Stage1View>& mask_views = training.mask_views;

  pipeline::Stage2Config cfg = config;
  // Stage2Config::fixed_material: the IoR and absorption held, nothing chosen
  std::optional<io::Material> held;
  if (!cfg.fixed_material.empty()) {
    held = io::read_material(cfg.fixed_material);
    cfg.optimize_ior = cfg.optimize_absorption = false;
    cfg.absorption_model = held->absorption == io::AbsorptionType::none          ? pipeline::AbsorptionModel::none
                           : held->absorption == io::AbsorptionType::homogeneous ? pipeline::AbsorptionModel::homogeneous
                                                                                 : pipeline::AbsorptionModel::grid;
    const std::vector<float> sigma = held->absorption == io::AbsorptionType::grid ? held->grid.sigma
                                     : std::vector<float>{held->sigma.x, held->sigma.y, held->sigma.z};
    inputs += " fixed material " + fingerprint(std::vector<float>{float(held->ior)}) + fingerprint(sigma);
  }
  {  // the absorption grid spans the mesh's box, a little grown
    Vec3f lo(1e30f), hi(-1e30f);
    for (const Vec3f& p : mesh.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    const Vec3f pad = 0.05f * (hi - lo) + Vec3f(1e-3f);
    cfg.box_lo = lo - pad;
    cfg.box_hi = hi + pad;
  }
  cfg.iterations = cfg.total_iterations();
  pipeline::write_fields(cfg, j["settings"]);
  j["training_views"] = views.size();

  progress("materials: " + std::to_string(cfg.iterations) + " iterations over " + std::to_string(views.size()) +
           " views, " + std::to_string(cfg.rays_per_iteration) + " rays each, IoR from " +
           (cfg.scans_ior() ? std::string("a scan") : fixed(cfg.ior_init, 3)) +
           ", absorption " +
           (cfg.absorption_model == pipeline::AbsorptionModel::automatic
                ? "chosen from none, homogeneous and grids up to " + std::to_string(cfg.absorption_res) + "^3"
            : cfg.absorption_model == pipeline::AbsorptionModel::grid
                ? "grid " + std::to_string(cfg.absorption_res) + "^3"
                : pipeline::detail::enum_name(cfg.absorption_model)) +
           (cfg.optimize_positions ? ", vertices after " + std::to_string(cfg.freeze_geometry) : std::string()));
  pipeline::Stage2 stage(s, views, mask_views, cfg);
  if (held) {  // after Stage2, which starts the material afresh
    render::set_material(s, *held);
    progress("materials: the IoR (" + fixed(s.ior, 4) + ") and the absorption held at " + cfg.fixed_material);
  }
  // --device: the training rays on the GPU (the rest of the stage on the host)
  const std::unique_ptr<GpuBatchTracer> gpu = gpu_batch_tracer_for(run.device, s, "materials");
  if (gpu) stage.set_batch_gradient(gpu_batch_gradient(*gpu));
  j["device"] = gpu ? "cuda" : "cpu";
  // the directions the training views' background saw (Stage2Config::unseen_sky)
  if (s.environment_width > 0 && !s.near_field)
    stage.set_seen_texels(pipeline::seen_texels(pipeline::background_observations(scene.train), s.environment_width,
                                                s.environment_height));
  // checkpoints: the settings above, the seed and the inputs name the run
  const fs::path ckpt_path = out / "checkpoint_stage2.bin";
  // (not the iteration count: a finished or stopped fit can be continued for more iterations)
  io::Json settings = j["settings"];
  // (nor what happens after the last iteration: the IoR's settling)
  for (const char* key : {"iterations", "test_spp_axis", "mesh", "ior_settle_batches", "ior_settle_step",
                          "ior_settle_rounds", "ior_settle_clip"})
    settings.erase(key);
  const std::string run_name = settings.dump() + " seed " + std::to_string(cfg.seed) + " " + inputs;
  if (!run.restart && fs::exists(ckpt_path)) {
    if (stage.load(ckpt_path, run_name))
      progress("materials: resuming from " + folder.shown(ckpt_path).string() + " at iteration " + std::to_string(stage.iteration()));
    else
      warn("materials: " + folder.shown(ckpt_path).string() +
           " is of other settings or inputs, lies past --materials-iterations, or is damaged; starting afresh");
  }
  j["resumed_at"] = stage.iteration();
  const auto save = [&] { stage.save(ckpt_path, run_name); };
  // With the vertices moving and a true mesh: the surface against the truth
  // at the start of the vertex phase and at the end of each of its levels
  // (λ, environment blur), logged and kept in materials.geometry_levels, to
  // see which levels help (docs/stage2-diagnostics.md).
  GeometryLevels levels(cfg.optimize_positions ? scene.gt.mesh : fs::path());
  std::size_t levels_shown = stage.vertex_levels().size();
  const auto t0 = clock::now();
  {  // the fit; outside it a signal ends the program at once (the checkpoint is complete)
    const StopSignals stop_signals;  // SIGINT / SIGTERM: save the checkpoint, then stop
    ProgressMeter meter("materials", cfg.iterations, stage.iteration());
    auto last_save = clock::now();
    while (!stage.done()) {
      const bool choosing = stage.iteration() == 0 && stage.absorption_choice().is_null() &&
                            cfg.absorption_model == pipeline::AbsorptionModel::automatic && cfg.optimize_absorption;
      if (choosing)
        progress("materials: choosing the absorption model on " + std::to_string(cfg.selection_batches) +
                 " held-out batches (every " + std::to_string(cfg.selection_holdout) + "th view; " +
                 std::to_string(cfg.selection_iterations) + " iterations per candidate)");
      const bool choosing_depth = stage.iteration() == 0 && cfg.choose_depth && stage.depth_choice().is_null();
      const bool scanning = stage.ior_scan().is_null();
      // the vertices about to move: the stage-1 mesh under the materials fitted so far
      if (cfg.optimize_positions && stage.iteration() == cfg.freeze_geometry)
        levels.record(to_io_mesh(s.mesh.positions, s.mesh.triangles), cfg.freeze_geometry, "stage 1");
      const bool settle_shown = stage.vertex_start_settle().has_value();
      const pipeline::Stage2Stats st = stage.step();
      if (!settle_shown && stage.vertex_start_settle())
        progress("materials: before the vertices move, " +
                 settle_text(*stage.vertex_start_settle(), "the mean of the last " +
                                                               std::to_string(cfg.ior_settle_window) + " iterations",
                             cfg.ior_settle_batches));
      // Stage2Config::level_loss_batches / keep_best_level: what the loss said
      for (; levels_shown < stage.vertex_levels().size(); ++levels_shown) {
        const io::Json& r = stage.vertex_levels()[levels_shown];
        progress("materials: vertices at iteration " + std::to_string(r.value("iteration", 0)) +
                 ": colour loss on fixed batches " + fixed(r.value("loss", 0.0), 5) + " +- " +
                 fixed(r.value("standard_error", 0.0), 5) +
                 (r.contains("above_best") ? ", against the best level's (iteration " +
                                                 std::to_string(r.value("best_iteration", 0)) + ") " +
                                                 fixed(r.value("above_best", 0.0), 5) + " +- " +
                                                 fixed(r.value("above_best_standard_error", 0.0), 5)
                                           : std::string()) +
                 ": " + r.value("decision", std::string()) +
                 (r.contains("vertex_steps")
                      ? "; its " + std::to_string(r.value("vertex_steps", 0)) + " steps before: scale " +
                            fixed(r.value("mean_vertex_scale", 0.0), 6) + ", agreement " +
                            fixed(r.value("mean_vertex_agreement", 0.0), 3) + ", peak " +
                            fixed(r.value("mean_vertex_peak", 0.0), 1)
                      : std::string()));
      }
      if (st.geometry_moving) levels.step(st, s.mesh);
      if (scanning && !stage.ior_scan().is_null())
        progress("materials: " + stage.ior_scan().value("summary", std::string()) + ", in " +
                 duration_text(stage.ior_scan().value("seconds", 0.0)));
      if (choosing) {
        const io::Json& c = stage.absorption_choice();
        progress("materials: absorption " + c.value("summary", std::string()) + ", in " +
                 duration_text(c.value("seconds", 0.0)));
        if (c.value("richest_still_improves", false))
          warn("materials: the finest absorption grid (" + std::to_string(cfg.absorption_res) +
               "^3) still lowers the held-out loss measurably: the absorption may vary more sharply than it resolves "
               "(raise --absorption-res)");
      }
      if (choosing_depth && !stage.depth_choice().is_null()) {
        const io::Json& d = stage.depth_choice();
        progress("materials: training depth " + std::to_string(d.value("depth", 0)) + " of " +
                 std::to_string(cfg.trace.max_depth) + " (the shallowest whose mean pixel is within its noise of the "
                 "deepest's over " + std::to_string(d.value("pixels", 0)) + " pixels), pruning at " +
                 fixed(d.value("prune", 0.0), 3) + " (least work x variance), in " +
                 duration_text(d.value("seconds", 0.0)));
      }
      meter.update(st.iteration + 1, "colour " + fixed(st.color, 5) + " IoR " + fixed(st.ior, 4) + " mean sigma (" +
                                         fixed(st.mean_sigma.x, 3) + ", " + fixed(st.mean_sigma.y, 3) + ", " +
                                         fixed(st.mean_sigma.z, 3) + ")" +
                                         (stage.sky_fitted() ? " sky x(" + fixed(st.sky_scale.x, 3) + ", " +
                                                                   fixed(st.sky_scale.y, 3) + ", " +
                                                                   fixed(st.sky_scale.z, 3) + ")"
                                                             : std::string()) +
                                         (st.geometry_moving ? " mask " + fixed(st.mask, 5) + " lambda " + fixed(st.lambda, 2) : std::string()) + "  " +
                                         fixed(st.seconds, 3) + " s/it" +
                                         (st.skipped_rays ? "  skipped " + std::to_string(st.skipped_rays) : std::string()));
      const int stop = stop_requested();  // read once: the save and the stop below agree
      if (stop || stage.done() ||
          (run.checkpoint_every > 0 && stage.iteration() % run.checkpoint_every == 0) ||
          std::chrono::duration<double>(clock::now() - last_save).count() > 60.0) {
        save();
        folder.commit();  // OUT now holds this checkpoint
        last_save = clock::now();
      }
      stop_if_requested("materials", "the fit at iteration " + std::to_string(stage.iteration()) + " is saved in " +
                                         folder.shown(ckpt_path).string(), stop);
    }
    meter.finish();
  }
  levels.finish(s.mesh, stage.iteration());
  if (!levels.json().empty()) j["geometry_levels"] = levels.json();
  if (!stage.vertex_levels().empty()) j["vertex_levels"] = stage.vertex_levels();
  if (stage.vertices_stopped_at() >= 0) j["vertices_stopped_at"] = stage.vertices_stopped_at();
  std::vector<double> color_curve, ior_curve;
  for (const pipeline::Stage2Stats& st : stage.history()) {
    color_curve.push_back(st.color);
    ior_curve.push_back(st.ior);
  }
  const double fit_seconds = std::chrono::duration<double>(clock::now() - t0).count();
  j["fit_seconds"] = fit_seconds;
  j["ior_last_iterate"] = s.ior;
  // the mean over the last iterations (Stage2Config::average_fraction), then
  // the root of the mean IoR gradient near it (Stage2::settle_ior)
  const pipeline::Stage2::IorSettle settle = stage.settle_ior();
  j["ior_averaged"] = settle.start;
  if (!settle.evaluations.empty()) {
    j["ior_settle"] = settle_record(settle);
    progress("materials: " + settle_text(settle, "the mean of the last iterations", cfg.ior_settle_batches));
  }
  if (const auto& before = stage.vertex_start_settle(); before && !before->evaluations.empty())
    j["ior_settle_before_vertices"] = settle_record(*before);
  s.ior = settle.ior;
  j["ior"] = s.ior;
  const Vec3f ms = stage.mean_sigma();
  j["mean_sigma"] = {ms.x, ms.y, ms.z};
  {  // the model fitted: given, or chosen from the photographs (its record)
    io::Json model = stage.absorption_choice();
    if (model.is_null()) model = {{"requested", pipeline::detail::enum_name(cfg.absorption_model)}};
    model["fitted"] = s.absorption_kind == scene::AbsorptionKind::grid          ? "grid"
                      : s.absorption_kind == scene::AbsorptionKind::homogeneous ? "homogeneous"
                                                                                : "none";
    if (s.absorption_kind == scene::AbsorptionKind::grid) model["fitted_res"] = s.absorption_res.x;
    j["absorption_model"] = model;
  }
  if (!stage.depth_choice().is_null()) j["depth_choice"] = stage.depth_choice();
  if (!stage.ior_scan().is_null()) j["ior_scan"] = stage.ior_scan();
  const Vec3f s0 = stage.searched_sigma();
  if (std::isfinite(s0.x)) {  // Stage2Config::sigma_search's choice and its evidence
    j["sigma_start"] = {s0.x, s0.y, s0.z};
    const pipeline::Stage2::SigmaSearchEvidence& ev = stage.sigma_search_evidence();
    io::Json rendered = io::Json::array();
    for (const auto& r : ev.rendered) rendered.push_back({r[0], r[1], r[2]});
    j["sigma_search"] = {{"sigma", ev.sigma},
                         {"rendered_sum", rendered},
                         {"photographed_sum", {ev.photographed[0], ev.photographed[1], ev.photographed[2]}}};
    // a clear object fits no σ: the search's σ (the homogeneous candidate's
    // start in the model choice, or the unseen sky's search) is not the fit's
    const bool sigma_unused = s.absorption_kind == scene::AbsorptionKind::none;
    if (sigma_unused) j["sigma_search"]["sigma_used"] = false;
    const Vec3f k0 = stage.searched_sky();
    if (std::isfinite(k0.x)) {  // Stage2Config::unseen_sky: the search's factor, per channel found with σ or not
      j["sigma_search"]["sky_start"] = {k0.x, k0.y, k0.z};
      j["sigma_search"]["sky_found_with_sigma"] = {ev.sky_joint[0], ev.sky_joint[1], ev.sky_joint[2]};
      progress("materials: starting factor of the unseen sky " + fixed(k0.x, 3) + ", " + fixed(k0.y, 3) + ", " +
               fixed(k0.z, 3) + " (with the absorption from two halves of the pixels" +
               (ev.sky_joint[0] && ev.sky_joint[1] && ev.sky_joint[2] ? ")" : "; not in every channel)"));
    }
    progress(std::string("materials: ") + (sigma_unused ? "the absorption search found " : "starting absorption ") +
             fixed(s0.x, 3) + ", " + fixed(s0.y, 3) + ", " + fixed(s0.z, 3) +
             " per unit length (the rendered light matched to the photographs' over " +
             std::to_string(ev.sigma.size()) + " grey values)" +
             (sigma_unused ? "; not used: the object was found clear" : ""));
  }

  // outputs: material, mesh, loss curve
  io::Material mat;
  mat.ior = s.ior;
  if (s.absorption_kind == scene::AbsorptionKind::grid) {
    mat.absorption = io::AbsorptionType::grid;
    mat.grid.res = s.absorption_res;
    mat.grid.lo = s.absorption_lo;
    mat.grid.hi = s.absorption_hi;
    mat.grid.sigma.resize(s.absorption_raw.size());
    for (std::size_t i = 0; i < s.absorption_raw.size(); ++i) mat.grid.sigma[i] = ad::softplus(s.absorption_raw[i]);
    mat.grid_file = "absorption_stage2.json";
  } else if (s.absorption_kind == scene::AbsorptionKind::homogeneous) {
    mat.absorption = io::AbsorptionType::homogeneous;
    mat.sigma = Vec3f(ad::softplus(s.absorption_raw[0]), ad::softplus(s.absorption_raw[1]),
                      ad::softplus(s.absorption_raw[2]));
  } else {
    mat.absorption = io::AbsorptionType::none;
  }
  io::write_material(out / "material_stage2.json", mat);
  if (mat.absorption != io::AbsorptionType::grid) {  // an earlier run's grid would be taken for this one's
    std::error_code ignored;
    fs::remove(out / "absorption_stage2.json", ignored);
  }
  io::write_mesh(out / "mesh_stage2.obj", to_io_mesh(s.mesh.positions, s.mesh.triangles));
  if (cfg.optimize_positions) {  // the surface before and after: speckle, folds, topology
    const metrics::MeshQuality q = metrics::mesh_quality(s.mesh.positions, s.mesh.triangles);
    j["mesh_quality"] = {{"stage1", mesh_quality_json(quality_in)}, {"stage2", mesh_quality_json(q)}};
    progress("materials: mesh mean dihedral angle " + fixed(quality_in.mean_dihedral_degrees, 2) + " -> " +
             fixed(q.mean_dihedral_degrees, 2) + " degrees, self-intersecting triangle pairs " +
             std::to_string(quality_in.self_intersections) + " -> " + std::to_string(q.self_intersections) +
             ", genus " + std::to_string(quality_in.genus) + " -> " + std::to_string(q.genus));
    if (q.self_intersections > quality_in.self_intersections || q.genus != quality_in.genus)
      warn("materials: moving the vertices changed the surface's topology or folded it through itself");
  }
  if (stage.sky_fitted()) {
    // the map with its unseen sky scaled: what the fit saw, and what the test renders use
    const Vec3f k = stage.unseen_sky_scale();
    io::Image map(s.environment_width, s.environment_height);
    map.rgb = s.environment;
    io::write_hdr(out / "envmap_stage2.hdr", map);
    j["unseen_sky"] = {{"scale", {k.x, k.y, k.z}},
                       {"solid_angle_fraction", stage.unseen_solid_angle_fraction()},
                       {"map", folder.shown(out / "envmap_stage2.hdr").string()}};
    progress("materials: the sky no background pixel saw (" + fixed(100.0 * stage.unseen_solid_angle_fraction(), 1) +
             " % of the sphere) scaled by " + fixed(k.x, 3) + ", " + fixed(k.y, 3) + ", " + fixed(k.z, 3) +
             " (envmap_stage2.hdr)");
  }
  write_loss_svg(out / "stage2_loss.svg", {{"colour loss (L2, training rays)", color_curve}, {"IoR", ior_curve}});

  // test views: renders, metrics, contact sheet
  const io::Split& test = scene.test.frames.empty() ? scene.train : scene.test;
  std::vector<View> test_views;
  for (const io::Frame& f : test.frames)
    if (!f.environment_only) test_views.push_back(view_from_frame(f));
  const render::PassOptions ref = render::reference_pass_options(8, cfg.test_spp_axis);
  const auto renders = render_views(s, test_views, ref, out / "stage2_test", false, "materials: test views");
  j["test"] = compare_with_truth(renders, nullptr, out / "stage2_test");
  j["test_split"] = scene.test.frames.empty() ? "train (no test split)" : "test";

  // against the ground truth: a report; a comparison that fails warns, the fit is kept
  try {
    if (!scene.gt.material.empty() && fs::exists(scene.gt.material)) {
      const io::Material gt = io::read_material(scene.gt.material);
      j["ior_true"] = gt.ior;
      j["ior_error"] = metrics::ior_error(s.ior, gt.ior);
    }
    if (!scene.gt.mesh.empty() && fs::exists(scene.gt.mesh)) {
      const io::Mesh gt_mesh = io::read_mesh(scene.gt.mesh);
      const auto g = metrics::evaluate_geometry(to_io_mesh(s.mesh.positions, s.mesh.triangles), gt_mesh);
      j["chamfer"] = g.chamfer;
      j["f1"] = g.f1;
      j["normal_error_deg"] =
          normal_error_json(metrics::normal_error(to_io_mesh(s.mesh.positions, s.mesh.triangles), gt_mesh));
      if (cfg.optimize_positions) {
        write_geometry_picture(out / "geometry_stage2.png", mesh, to_io_mesh(s.mesh.positions, s.mesh.triangles),
                               gt_mesh);
        j["geometry_picture"] = folder.shown(out / "geometry_stage2.png").string();
      }
      if (!scene.gt.material.empty() && fs::exists(scene.gt.material)) {
        // the fitted grid against the true absorption inside the true object
        const io::Material gt = io::read_material(scene.gt.material);
        const std::vector<Vec3f> inside =
            metrics::interior_points(gt_mesh.positions, gt_mesh.triangles, absorption_error_lattice);
        const auto fitted = [&](const Vec3f& p) {
          return mat.absorption == io::AbsorptionType::grid          ? metrics::grid_sigma_at(mat.grid, p)
                 : mat.absorption == io::AbsorptionType::homogeneous ? mat.sigma
                                                                     : Vec3f(0.0f);
        };
        const auto truth = [&](const Vec3f& p) {
          return gt.absorption == io::AbsorptionType::grid          ? metrics::grid_sigma_at(gt.grid, p)
                 : gt.absorption == io::AbsorptionType::homogeneous ? gt.sigma
                                                                    : Vec3f(0.0f);
        };
        const auto e = metrics::absorption_error(inside, fitted, truth);
        j["absorption_error"] = {{"relative", e.relative},        {"mean_relative", e.mean_relative},
                                 {"mean_true", e.mean_true},      {"mean_fit", e.mean_fit},
                                 {"mean_absolute", e.mean_abs},   {"points", e.points}};
        // where along the height it lies (docs/metrics.md): 8 slabs of the object along y
        const metrics::AbsorptionSlabs slabs = metrics::absorption_slabs(inside, fitted, truth, 1, 8);
        j["absorption_error"]["slabs"] = {{"axis", "y"},
                                          {"from", slabs.slabs.from},
                                          {"to", slabs.slabs.to},
                                          {"points", slabs.points},
                                          {"mean_true", slabs.mean_true},
                                          {"mean_fit", slabs.mean_fit}};
      }
    }
  } catch (const std::exception& e) {
    warn(std::string("materials: no comparison with the ground truth: ") + e.what());
    j["ground_truth_error"] = e.what();
  }
  progress("materials: IoR " + fixed(s.ior, 4) +
           (j.contains("ior_error") ? " (error " + fixed(j["ior_error"].get<double>(), 4) + ")" : std::string()) +
           (j.contains("absorption_error") ? absorption_error_text(j["absorption_error"]) : std::string()) +
           (cfg.optimize_positions && j.contains("normal_error_deg")
                ? ", CD " + fixed(j["chamfer"].get<double>(), 6) + ", normals off by " +
                      fixed(j["normal_error_deg"]["mean"].get<double>(), 2) + " deg on average"
                : std::string()) +
           ", test PSNR " + fixed(j["test"].value("psnr", 0.0), 2) + " dB, fitted in " + duration_text(fit_seconds));
  j["peak_memory_mb"] = peak_memory_mb();
  j["seconds"] = std::chrono::duration<double>(clock::now() - t_start).count();
  return j;
}

}  // namespace difftrans::cli
