// difftrans reconstruct --stages geometry: stage 1, the shape from the masks
// (FlexiCubes + differentiable silhouettes, then remeshing and large-steps
// refinement). Writes mesh_stage1_raw.obj, mesh_stage1.obj, a strip of masks
// against rendered silhouettes, the loss curve, and CD / F1 / genus when the
// scene has a ground-truth mesh. Resumable: the FlexiCubes unknowns are saved
// to checkpoint_stage1.bin as it runs (removed once the raw mesh is written),
// and a finished raw mesh is reused.
#include "long_run.hpp"
#include "stages.hpp"
#include "stage_output.hpp"

#include <algorithm>
#include <chrono>
#include <exception>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <system_error>
#include <sys/resource.h>

#include "config_options.hpp"
#include "pipeline/geometry_refine.hpp"
#include "difftrans/io/contact_sheet.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/io/png.hpp"
#include "difftrans/metrics/chamfer.hpp"
#include "difftrans/metrics/normals.hpp"

namespace difftrans::cli {
namespace {

namespace dg = difftrans::geometry;
using clock_type = std::chrono::steady_clock;

double seconds_since(clock_type::time_point t) { return std::chrono::duration<double>(clock_type::now() - t).count(); }


void from_io_mesh(const io::Mesh& m, std::vector<float>& pos, std::vector<std::int32_t>& tris) {
  pos.clear();
  tris.clear();
  for (const Vec3f& p : m.positions) pos.insert(pos.end(), {p.x, p.y, p.z});
  for (const Vec3i& t : m.triangles) tris.insert(tris.end(), {t.x, t.y, t.z});
}

// Rows: target mask | rendered silhouette of the mesh | difference (red: mask
// not covered, blue: covered outside the mask).
void write_silhouette_strip(const std::filesystem::path& path, const std::vector<pipeline::Stage1View>& views,
                            const std::vector<float>& pos, const std::vector<std::int32_t>& tris, int count) {
  if (views.empty() || tris.empty()) return;
  const scene::TriangleMesh m(pos, tris);
  const geometry::TriangleNeighbors nb = geometry::TriangleNeighbors::build(m);
  const auto picked = io::spread_indices(int(views.size()), count);
  io::SheetLayout layout;
  layout.tile_width = views.front().camera.width;
  layout.tile_height = views.front().camera.height;
  layout.rows = int(picked.size());
  layout.cols = 3;
  std::vector<std::vector<io::Image8>> tiles;
  for (int i : picked) {
    const pipeline::Stage1View& v = views[std::size_t(i)];
    if (v.camera.width != layout.tile_width || v.camera.height != layout.tile_height) continue;
    const std::vector<float> s = render::silhouette_mask<float>(m, v.camera, &nb);
    const std::size_t n = s.size();
    io::Image8 a{layout.tile_width, layout.tile_height, 3, std::vector<std::uint8_t>(3 * n)}, b = a, d = a;
    for (std::size_t p = 0; p < n; ++p) {
      const float t = std::clamp(v.target[p], 0.0f, 1.0f), r = std::clamp(s[p], 0.0f, 1.0f);
      for (int c = 0; c < 3; ++c) {
        a.data[3 * p + std::size_t(c)] = std::uint8_t(255.0f * t + 0.5f);
        b.data[3 * p + std::size_t(c)] = std::uint8_t(255.0f * r + 0.5f);
      }
      const float miss = std::max(0.0f, t - r), extra = std::max(0.0f, r - t);
      d.data[3 * p] = std::uint8_t(255.0f * miss + 0.5f);
      d.data[3 * p + 1] = 0;
      d.data[3 * p + 2] = std::uint8_t(255.0f * extra + 0.5f);
    }
    tiles.push_back({std::move(a), std::move(b), std::move(d)});
  }
  layout.rows = int(tiles.size());
  if (!tiles.empty()) io::write_png8(path, io::compose_sheet(layout, tiles));
}

io::Json geometry_record(const std::vector<float>& pos, const std::vector<std::int32_t>& tris) {
  const dg::MeshGenus g = dg::mesh_genus(tris, std::int32_t(pos.size() / 3));
  io::Json j;
  j["vertices"] = g.vertices;
  j["triangles"] = g.faces;
  j["components"] = g.components;
  j["euler_characteristic"] = g.euler;
  j["genus"] = g.genus;
  j["closed"] = g.closed;
  return j;
}

}  // namespace

void add_geometry_options(CLI::App* cmd, GeometryOptions& opt) {
  add_config_options(cmd, opt.config, "Geometry: ");
  cmd->add_option("--schedule", opt.schedule,
                  "Geometry: MASK_ONLY,PERIOD,DEVELOPABILITY_START iterations (default: 10 %, 5 %, 80 % of --iterations, "
                  "the paper's 100,50,800 for 1000)");
  std::string names;
  pipeline::Stage1Weights::fields(opt.config.weights, [&](const pipeline::Field& f, float&) {
    names += (names.empty() ? "" : ", ") + std::string(f.key);
  });
  cmd->add_option("--weights", opt.weights, "Geometry: loss weights NAME=VALUE,... (" + names + ")");
}

io::Json geometry_stage(const io::Scene& scene, RunFolder& folder, const GeometryOptions& opt,
                        const RunOptions& run) {
  const auto t_start = clock_type::now();
  namespace fs = std::filesystem;
  // training views with masks
  std::vector<pipeline::Stage1View> views;
  for (const io::Frame& f : scene.train.frames) {
    if (f.mask.width == 0) {
      warn("geometry: frame " + f.name + " has no mask; it is not used");
      continue;
    }
    pipeline::Stage1View v;
    v.camera = render::camera_of(f);
    if (f.mask.width != v.camera.width || f.mask.height != v.camera.height)
      throw std::runtime_error("geometry: the mask of frame " + f.name + " does not match its camera's size");
    v.target.resize(f.mask.inside.size());
    for (std::size_t p = 0; p < v.target.size(); ++p) v.target[p] = f.mask.inside[p] ? 1.0f : 0.0f;
    views.push_back(std::move(v));
  }
  if (views.empty()) throw std::runtime_error("geometry: no training frame has a mask");

  pipeline::Stage1Config cfg = opt.config;
  std::stringstream weights(opt.weights);  // --weights NAME=VALUE,...
  for (std::string item; std::getline(weights, item, ',');) {
    if (item.empty()) continue;
    const auto eq = item.find('=');
    float* w = nullptr;
    pipeline::Stage1Weights::fields(cfg.weights, [&](const pipeline::Field& f, float& value) {
      if (item.compare(0, eq, f.key) == 0 && std::string(f.key).size() == eq) w = &value;
    });
    if (!w || eq == std::string::npos) throw std::runtime_error("--weights: '" + item + "' is not NAME=VALUE with a known NAME");
    try {
      *w = std::stof(item.substr(eq + 1));
    } catch (const std::exception&) {
      throw std::runtime_error("--weights: '" + item + "' has no number after '='");
    }
  }
  // the schedule scales with the iteration count (the paper's: 1000 = 100 mask + 50-periods, developability from 800)
  cfg.mask_only_iterations = std::max(1, cfg.iterations / 10);
  cfg.alternate_period = std::max(1, cfg.iterations / 20);
  cfg.developability_start = cfg.iterations * 8 / 10;
  if (!opt.schedule.empty()) {  // MASK_ONLY,PERIOD,DEVELOPABILITY_START
    std::stringstream ss(opt.schedule);
    std::vector<int> v;
    for (std::string item; std::getline(ss, item, ',');) {
      try {
        std::size_t used = 0;
        v.push_back(std::stoi(item, &used));
        if (used != item.size()) throw std::invalid_argument(item);
      } catch (const std::exception&) {
        throw std::runtime_error("--schedule: '" + item + "' is not an integer (expected MASK_ONLY,PERIOD,DEVELOPABILITY_START)");
      }
    }
    if (v.size() != 3 || v[0] < 0 || v[1] < 1 || v[2] < 0)
      throw std::runtime_error("--schedule: '" + opt.schedule +
                               "' is not MASK_ONLY,PERIOD,DEVELOPABILITY_START (iterations >= 0, period >= 1)");
    cfg.mask_only_iterations = v[0];
    cfg.alternate_period = v[1];
    cfg.developability_start = v[2];
  }
  if (scene.settings.aabb && !scene.settings.aabb->empty()) {
    // a cube around scene.json's box: FlexiCubes cells stay cubes, so the
    // learning rate (in world units) means the same number of cells on every
    // axis (a flat box's thin axis would otherwise get cells several times
    // smaller than a step, and its surface would fall apart into foam)
    const Vec3f lo(scene.settings.aabb->lo), hi(scene.settings.aabb->hi), c = 0.5f * (lo + hi);
    const float half = 0.5f * std::max(hi.x - lo.x, std::max(hi.y - lo.y, hi.z - lo.z));
    cfg.box_lo = c - Vec3f(half);
    cfg.box_hi = c + Vec3f(half);
  } else {
    pipeline::stage1_unit_box(cfg, cfg.box_margin);
  }

  const fs::path& out = folder.work();
  const fs::path raw_path = out / "mesh_stage1_raw.obj", final_path = out / "mesh_stage1.obj",
                 ckpt_path = out / "checkpoint_stage1.bin";
  io::Json j;
  pipeline::write_fields(cfg, j["settings"]);
  j["training_views"] = views.size();

  // ---- FlexiCubes (or the finished raw mesh)
  std::vector<float> raw_pos;
  std::vector<std::int32_t> raw_tris;
  std::vector<double> fc_loss, fc_mask;
  double fc_seconds = 0.0, mean_iteration = 0.0;
  if (!run.restart && fs::exists(raw_path)) {
    progress("geometry: reusing " + folder.shown(raw_path).string() + " (finished earlier; --restart recomputes it)");
    from_io_mesh(io::read_mesh(raw_path), raw_pos, raw_tris);
    j["raw_reused"] = true;
  } else {
    const auto t0 = clock_type::now();
    pipeline::Stage1FlexiCubes fc(cfg);
    bool resumed = false;
    if (!run.restart && fs::exists(ckpt_path)) {
      resumed = fc.load(ckpt_path);
      if (resumed)
        progress("geometry: resuming from " + folder.shown(ckpt_path).string() + " at iteration " + std::to_string(fc.iteration()));
      else
        warn("geometry: " + folder.shown(ckpt_path).string() + " is for another grid or unreadable; starting afresh");
    }
    if (!resumed && cfg.init == pipeline::Stage1Init::hull) fc.init_visual_hull(views);
    fc.set_carving(views);
    j["carved_grid_vertices"] = fc.carved_vertices();
    j["resumed_at"] = fc.iteration();
    progress("geometry: FlexiCubes " + std::to_string(cfg.grid_resolution) + "^3 over " + std::to_string(views.size()) +
             " views, " + std::to_string(cfg.iterations) + " iterations, " + std::to_string(cfg.views_per_iteration) +
             " views per iteration");
    auto last_save = clock_type::now();
    io::Json genus_history = io::Json::array();
    double sum_it = 0.0;
    int counted = 0;
    const StopSignals stop_signals;  // SIGINT / SIGTERM: save the checkpoint, then stop
    ProgressMeter meter("geometry", cfg.iterations, fc.iteration());
    while (!fc.done()) {
      const pipeline::Stage1Stats s = fc.step(views);
      sum_it += s.seconds;
      ++counted;
      const bool last = fc.done();
      meter.update(s.iteration + 1, std::string("[") + s.phase + "] loss " + fixed(s.loss, 5) + " mask " +
                                        fixed(s.mask, 5) + " lr " + fixed(s.lr, 5) + "  " + std::to_string(s.triangles) +
                                        " tris  " + fixed(s.seconds, 3) + " s/it (extract " + fixed(s.extract_seconds, 3) +
                                        ", silhouettes " + fixed(s.render_seconds, 3) + ", backward " +
                                        fixed(s.backward_seconds, 3) + ")");
      if (stop_requested()) {
        fc.save(ckpt_path);
        stop_if_requested("geometry", "the FlexiCubes state at iteration " + std::to_string(fc.iteration()) +
                                          " is saved in " + folder.shown(ckpt_path).string());
      }
      if (last || (run.checkpoint_every > 0 && fc.iteration() % run.checkpoint_every == 0) ||
          seconds_since(last_save) > 60.0) {
        fc.save(ckpt_path);
        folder.commit();  // OUT now holds this checkpoint
        last_save = clock_type::now();
        // the topology as it evolves (the largest component's genus is what the refinement keeps)
        const dg::FlexiCubesMesh<float> now = fc.extract(dg::QuadSplit::two_triangles);
        std::vector<float> p;
        for (const Vec3f& v : now.vertices) p.insert(p.end(), {v.x, v.y, v.z});
        std::vector<std::int32_t> t = now.triangles;
        const dg::MeshGenus all = dg::mesh_genus(t, std::int32_t(p.size() / 3));
        dg::drop_small_components(p, t);
        const dg::MeshGenus kept = dg::mesh_genus(t, std::int32_t(p.size() / 3));
        genus_history.push_back({{"iteration", fc.iteration()}, {"components", all.components}, {"genus", all.genus},
                                 {"genus_after_dropping", kept.genus}});
        progress("geometry: checkpoint at it " + std::to_string(fc.iteration()) + ": " + std::to_string(all.components) +
                 " component(s), genus " + std::to_string(all.genus) + " (" + std::to_string(kept.genus) +
                 " without small components)");
      }
    }
    meter.finish();
    mean_iteration = counted ? sum_it / counted : 0.0;
    j["genus_history"] = genus_history;
    fc_loss = fc.loss_history();
    fc_mask = fc.mask_history();
    const dg::FlexiCubesMesh<float> mesh = fc.extract(dg::QuadSplit::two_triangles);
    for (const Vec3f& v : mesh.vertices) raw_pos.insert(raw_pos.end(), {v.x, v.y, v.z});
    raw_tris = mesh.triangles;
    if (raw_tris.empty()) throw std::runtime_error("geometry: the FlexiCubes grid holds no surface at the end");
    io::write_mesh(raw_path, to_io_mesh(raw_pos, raw_tris));
    // the raw mesh is what a later run reuses; the FlexiCubes state (79 MB at
    // a 128^3 grid) would only be copied at every publication of the folder
    std::error_code ignored;
    fs::remove(ckpt_path, ignored);
    fc_seconds = seconds_since(t0);
    j["flexicubes_seconds"] = fc_seconds;
    j["seconds_per_iteration"] = mean_iteration;
    progress("geometry: wrote " + folder.shown(raw_path).string() + " (" + fixed(fc_seconds, 1) + " s)");
  }
  j["raw"] = geometry_record(raw_pos, raw_tris);
  j["raw"]["mask_l1_train"] = pipeline::stage1_mask_error(raw_pos, raw_tris, views);

  // ---- remeshing and large-steps refinement
  std::vector<float> pos = raw_pos;
  std::vector<std::int32_t> tris = raw_tris;
  const int dropped = dg::drop_small_components(pos, tris);
  j["dropped_components"] = dropped;
  if (dropped) progress("geometry: dropped " + std::to_string(dropped) + " small component(s) before remeshing");
  std::vector<double> ref_loss;
  if (!run.restart && fs::exists(final_path) && j.contains("raw_reused")) {
    progress("geometry: reusing " + folder.shown(final_path).string());
    from_io_mesh(io::read_mesh(final_path), pos, tris);
  } else {
    const auto t1 = clock_type::now();
    progress("geometry: remeshing and " + std::to_string(cfg.refine_iterations) + " large-steps iterations");
    const StopSignals stop_signals;  // SIGINT / SIGTERM: save the checkpoint, then stop
    ProgressMeter meter("geometry: refine", cfg.refine_iterations);
    const pipeline::Stage1RefineResult r = pipeline::stage1_refine(pos, tris, views, cfg, [&](const pipeline::Stage1RefineStats& s) {
      meter.update(s.iteration + 1, "loss " + fixed(s.loss, 5) + " mask " + fixed(s.mask, 5) + "  " +
                                        fixed(s.seconds, 3) + " s/it");
      // the refinement is short and keeps no checkpoint: the FlexiCubes mesh is what is saved
      stop_if_requested("geometry", "the FlexiCubes mesh is saved in " + folder.shown(raw_path).string() +
                                        "; the refinement starts again from it");
    });
    meter.finish();
    if (!r.remeshed) warn("geometry: the remesher did not accept the mesh (not a closed manifold); refined as extracted");
    pos = r.positions;
    tris = r.triangles;
    ref_loss = r.loss;
    io::write_mesh(final_path, to_io_mesh(pos, tris));
    j["remeshed"] = r.remeshed;
    j["remesh_target_length"] = r.target_length;
    if (r.sizing_max > 0.0f) {
      j["remesh_sizing"] = {{"min", r.sizing_min}, {"median", r.sizing_median}, {"max", r.sizing_max}};
      progress("geometry: remeshed by curvature to edges of " + fixed(r.sizing_min, 4) + " to " +
               fixed(r.sizing_max, 4) + " (median " + fixed(r.sizing_median, 4) + "), " +
               std::to_string(pos.size() / 3) + " vertices");
    }
    j["remesh_seconds"] = r.remesh_seconds;
    j["refine_seconds"] = r.refine_seconds;
    j["refine_total_seconds"] = seconds_since(t1);
    progress("geometry: wrote " + folder.shown(final_path).string());
  }
  j["final"] = geometry_record(pos, tris);
  j["final"]["mask_l1_train"] = pipeline::stage1_mask_error(pos, tris, views);

  // ---- pictures
  write_silhouette_strip(out / "stage1_silhouettes.png", views, pos, tris, cfg.sheet_views);
  if (!fc_loss.empty() || !ref_loss.empty())
    write_loss_svg(out / "stage1_loss.svg",
                   {{"FlexiCubes total", fc_loss}, {"FlexiCubes mask L1", fc_mask}, {"refinement (mask + edge)", ref_loss}});

  // ---- metrics against the ground truth (docs/metrics.md: both normalized with the truth's unit-box transform)
  // (a report: a failure is a warning, the stage's results stand)
  if (!scene.gt.mesh.empty() && fs::exists(scene.gt.mesh)) {
    try {
      const io::Mesh gt = io::read_mesh(scene.gt.mesh);
      metrics::GeometryOptions go;
      go.samples = std::size_t(cfg.metric_samples);
      const auto raw_m = metrics::evaluate_geometry(to_io_mesh(raw_pos, raw_tris), gt, go);
      const auto fin_m = metrics::evaluate_geometry(to_io_mesh(pos, tris), gt, go);
      const std::vector<std::int32_t> gt_tris = [&] {
        std::vector<std::int32_t> t;
        for (const Vec3i& x : gt.triangles) t.insert(t.end(), {x.x, x.y, x.z});
        return t;
      }();
      j["raw"]["chamfer"] = raw_m.chamfer;
      j["raw"]["f1"] = raw_m.f1;
      j["final"]["chamfer"] = fin_m.chamfer;
      j["final"]["f1"] = fin_m.f1;
      const metrics::NormalError fin_n = metrics::normal_error(to_io_mesh(pos, tris), gt, go);
      j["raw"]["normal_error_deg"] = normal_error_json(metrics::normal_error(to_io_mesh(raw_pos, raw_tris), gt, go));
      j["final"]["normal_error_deg"] = normal_error_json(fin_n);
      j["gt_genus"] = dg::mesh_genus(gt_tris, std::int32_t(gt.positions.size())).genus;
      progress("geometry: CD " + fixed(fin_m.chamfer, 6) + " F1 " + fixed(fin_m.f1, 4) + ", normals off by " + fixed(fin_n.mean_deg, 2) +
               " deg on average (raw: CD " +
               fixed(raw_m.chamfer, 6) + " F1 " + fixed(raw_m.f1, 4) + ")");
    } catch (const std::exception& e) {
      warn(std::string("geometry: no comparison with the ground truth: ") + e.what());
      j["ground_truth_error"] = e.what();
    }
  }
  j["seconds"] = seconds_since(t_start);
  j["peak_memory_mb"] = peak_memory_mb();
  return j;
}

}  // namespace difftrans::cli
