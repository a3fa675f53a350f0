// difftrans report: the paper's experiments as one page. A suite (tiny,
// quick, full) is a list of difftrans runs — synthesize the benchmark scenes,
// reconstruct them, relight them, render at many speed settings, small
// studies (IoR sweep, ablations) — run one after another as child processes
// (report_jobs.hpp), then read back into tables and plots (report_page.hpp).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "command.hpp"
#include "long_run.hpp"
#include "report_jobs.hpp"
#include "report_page.hpp"
#include "difftrans/io/image_file.hpp"
#include "difftrans/io/png.hpp"
#include "difftrans/io/material.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/render/hard_cases.hpp"
#include "difftrans/render/passes.hpp"
#include "difftrans/render/views.hpp"
#include "difftrans/scene/camera.hpp"

#ifndef DIFFTRANS_BUILD_FLAGS
#define DIFFTRANS_BUILD_FLAGS "unknown"
#endif

namespace difftrans::cli {
namespace {

using namespace report;
using Args = std::vector<std::string>;

// What a suite runs. Scenes are the benchmark presets; the studies (IoR
// sweep, ablations, iteration counts) run on a smaller scene of their own.
struct Suite {
  std::string name;
  std::vector<std::string> scenes;
  Args synth, stage1, stage2;
  int relight_views = 10;
  bool tone_on_scenes = false;  // the tone ablation on every scene (else on the study scene)
  Args study_synth, study_stage1, study_stage2;
  std::vector<std::string> iors;
  std::vector<int> mask_noise;  // pixels of erosion and of dilation
  std::vector<int> mask_blobs;  // random discs flipped per mask
  std::string blob_radius = "3";
  std::vector<std::string> stage1_iterations;
  std::vector<std::string> stage1_batches;  // training views per stage-1 iteration (the default is 8)
  int speed_resolution = 128, speed_views = 2, reference_depth = 16, reference_spp_axis = 16;
  int gradient_size = 48;  // the gradient sweep's image side
  std::vector<int> depths, spp_axes;
  std::vector<std::string> roulettes;
};

Suite make_suite(const std::string& name) {
  Suite s;
  s.name = name;
  if (name == "tiny") {
    s.scenes = {"spot-clear"};
    s.synth = {"--variant", "test", "--resolution", "24", "--views", "12", "--test-views", "4", "--spp-axis", "2"};
    s.stage1 = {"--grid", "16", "--iterations", "40", "--refine-iterations", "20", "--env-model", "distant"};
    // the vertices move in iterations 20 to 26 (two blur levels), then the materials settle
    s.stage2 = {"--materials-iterations", "30", "--materials-freeze", "20", "--materials-geometry-iterations", "6",
                "--materials-blur-halving", "3", "--materials-rays", "512"};
    s.relight_views = 1;
    s.study_synth = {"--variant", "test", "--resolution", "24", "--views", "12", "--test-views", "2", "--spp-axis", "2"};
    s.study_stage1 = s.stage1;
    s.study_stage2 = s.stage2;
    s.iors = {"1.3", "1.8"};
    s.mask_noise = {1};
    s.mask_blobs = {2}, s.blob_radius = "2";
    s.stage1_iterations = {"20"};
    s.stage1_batches = {"2"};
    s.speed_resolution = 24, s.speed_views = 1, s.reference_spp_axis = 8, s.gradient_size = 16;
    s.depths = {2, 16}, s.spp_axes = {1, 4}, s.roulettes = {"0", "0.01"};
  } else if (name == "quick") {
    s.scenes = {"spot-clear", "bunny-clear", "horse-green", "monkey-bands"};
    s.synth = {"--variant", "quick"};
    s.relight_views = 4;
    s.study_synth = {"--variant", "test"};
    s.study_stage1 = {"--grid", "32", "--iterations", "300", "--refine-iterations", "300", "--env-model", "distant"};
    // the demo's short stage 2: the vertices move in iterations 60 to 160
    s.study_stage2 = {"--materials-iterations", "200", "--materials-freeze", "60", "--materials-geometry-iterations", "100",
                      "--materials-blur-halving", "50"};
    s.iors = {"1.3", "1.4", "1.5", "1.6", "1.8"};
    s.mask_noise = {1, 3};
    s.mask_blobs = {3};
    s.stage1_iterations = {"75", "150"};
    s.stage1_batches = {"2", "4"};
    s.speed_resolution = 128, s.speed_views = 2, s.reference_spp_axis = 16;
    s.depths = {2, 4, 8, 16}, s.spp_axes = {1, 2, 4}, s.roulettes = {"0", "0.01"};
  } else if (name == "full") {
    s.scenes = {"spot-clear", "bunny-clear", "horse-green", "monkey-bands"};
    s.synth = {"--variant", "full"};
    s.relight_views = 10;
    s.tone_on_scenes = true;
    s.study_synth = {"--variant", "quick"};
    s.iors = {"1.3", "1.4", "1.5", "1.6", "1.8"};
    s.mask_noise = {1, 2, 3};
    s.mask_blobs = {3, 8}, s.blob_radius = "4";
    s.stage1_iterations = {"250", "500"};
    s.stage1_batches = {"2", "4"};
    s.speed_resolution = 256, s.speed_views = 4, s.reference_spp_axis = 16, s.gradient_size = 96;
    s.depths = {2, 4, 8, 16}, s.spp_axes = {1, 2, 4, 8}, s.roulettes = {"0", "0.01", "0.03"};
  } else {
    throw std::runtime_error("report: unknown suite '" + name + "' (tiny, quick, full)");
  }
  return s;
}

Args cat(Args a, const Args& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// `base` with the options of `changes` ("--name value" pairs) replacing its
// own of the same name (the command takes each option once).
Args override_args(const Args& base, const Args& changes) {
  Args a;
  for (std::size_t i = 0; i < base.size(); ++i) {
    const bool replaced = base[i].rfind("--", 0) == 0 && std::find(changes.begin(), changes.end(), base[i]) != changes.end();
    if (replaced) {
      if (i + 1 < base.size() && base[i + 1].rfind("--", 0) != 0) ++i;  // its value
      continue;
    }
    a.push_back(base[i]);
  }
  return cat(a, changes);
}

// The paper's figures, for comparison (its scenes are not ours: only the
// shapes match by name).
struct PaperIor {
  const char* scene;
  const char* shape;
  double found, truth;
};
constexpr PaperIor paper_iors[] = {{"horse-green", "horse", 1.450, 1.540},
                                   {"monkey-bands", "monkey", 1.600, 1.577},
                                   {"bunny-clear", "bunny", 1.485, 1.471},
                                   {"spot-clear", "cow", 1.472, 1.472}};

// The run list of a suite.
struct Plan {
  std::vector<Job> jobs;
  void add(Job j) { jobs.push_back(std::move(j)); }
};

std::string sid(const std::string& scene, const std::string& what) { return scene + "/" + what; }

Plan make_plan(const Suite& s) {
  Plan p;
  const Args stages1 = {"--stages", "environment,geometry"}, stages2 = {"--stages", "materials"};
  // the benchmark scenes: synth, stage 1, stage 2 (the defaults: the vertices with the materials), stage 2 on the
  // stage-1 mesh (the materials alone), relighting
  for (const auto& sc : s.scenes) {
    const std::string scene = "@WORK/" + sid(sc, "scene") + "/out";
    p.add({sid(sc, "scene"), "synthesize " + sc, cat({"synth", "--preset", sc, "--out", "@OUT"}, s.synth), "", {}});
    p.add({sid(sc, "stage1"), "stage 1 of " + sc, cat(cat({"reconstruct", scene, "--out", "@OUT"}, stages1), s.stage1), "",
           {sid(sc, "scene")}});
    p.add({sid(sc, "stage2"), "stage 2 of " + sc, cat(cat({"reconstruct", scene, "--out", "@OUT"}, stages2), s.stage2),
           sid(sc, "stage1"), {sid(sc, "scene")}});
    p.add({sid(sc, "materials-only"), "stage 2 with the vertices held (the materials alone), " + sc,
           cat(cat(cat({"reconstruct", scene, "--out", "@OUT"}, stages2), s.stage2), {"--materials-geometry=false"}),
           sid(sc, "stage1"), {sid(sc, "scene")}});
    if (s.tone_on_scenes)
      p.add({sid(sc, "tone-off"), "stage 2 without the tone term, " + sc,
             cat(cat(cat({"reconstruct", scene, "--out", "@OUT"}, stages2), s.stage2), {"--materials-tone", "0"}),
             sid(sc, "stage1"), {sid(sc, "scene")}});
    const std::string rec = "@WORK/" + sid(sc, "stage2") + "/out";
    p.add({sid(sc, "relight"), "relight the reconstruction of " + sc,
           {"relight", "--mesh", rec + "/mesh_stage2.obj", "--material", rec + "/material_stage2.json", "--scene", scene,
            "--all-envs", "--views", std::to_string(s.relight_views), "--out", "@OUT"},
           "",
           {sid(sc, "stage2")}});
  }
  // speed against error: the true spot-clear object rendered at many settings and a converged reference
  {
    const std::string base = s.scenes.front();
    const std::string gt = "@WORK/" + sid(base, "scene") + "/out/gt";
    const Args common = {"render", "--mesh", gt + "/mesh.obj", "--material", gt + "/material.json", "--env", gt + "/envmap.hdr",
                         "--views", std::to_string(s.speed_views), "--resolution", std::to_string(s.speed_resolution),
                         "--out", "@OUT"};
    p.add({"speed/reference", "converged render (depth " + std::to_string(s.reference_depth) + ", " +
                                  std::to_string(s.reference_spp_axis) + "x" + std::to_string(s.reference_spp_axis) + " samples)",
           cat(common, {"--max-depth", std::to_string(s.reference_depth), "--spp-axis", std::to_string(s.reference_spp_axis)}), "",
           {sid(base, "scene")}});
    for (const auto& r : s.roulettes)
      for (int d : s.depths)
        for (int n : s.spp_axes) {
          const std::string id = "speed/d" + std::to_string(d) + "-s" + std::to_string(n) + "-r" + r;
          Args a = cat(common, {"--max-depth", std::to_string(d), "--spp-axis", std::to_string(n)});
          if (r != "0") a = cat(a, {"--roulette", r});
          p.add({id, "render at depth " + std::to_string(d) + ", " + std::to_string(n) + "x" + std::to_string(n) + " samples, roulette " + r,
                 a, "", {sid(base, "scene")}});
        }
  }
  // the study scene: spot-clear at the study variant
  const std::string study = "@WORK/study/scene/out";
  p.add({"study/scene", "synthesize the study scene (spot-clear)", cat({"synth", "--preset", "spot-clear", "--out", "@OUT"}, s.study_synth),
         "", {}});
  const auto reconstruct_study = [&](const std::string& id, const std::string& title, const std::string& scene_id, Args extra1,
                                     Args extra2) {
    const std::string scene = "@WORK/" + scene_id + "/out";
    p.add({id, title,
           cat(cat({"reconstruct", scene, "--out", "@OUT", "--stages", "environment,geometry,materials"},
                   override_args(s.study_stage1, extra1)),
               override_args(s.study_stage2, extra2)),
           "",
           {scene_id}});
  };
  reconstruct_study("study/default", "study scene, defaults", "study/scene", {}, {});
  if (!s.tone_on_scenes)
    reconstruct_study("study/tone-off", "study scene without the tone term", "study/scene", {}, {"--materials-tone", "0"});
  reconstruct_study("study/no-dilation", "study scene, stage 1 without the dilation term", "study/scene", {"--weights", "dilation=0"}, {});
  reconstruct_study("study/no-smoothness", "study scene, stage 1 without the smoothness term", "study/scene",
                    {"--weights", "smoothness=0"}, {});
  reconstruct_study("study/no-carving", "study scene, stage 1 without carving", "study/scene", {"--carve-margin", "-1"}, {});
  for (int k : s.mask_noise)
    for (const std::string how : {"erode", "dilate"}) {
      const std::string id = "study/mask-" + how + "-" + std::to_string(k);
      p.add({id + "-scene", "study scene, masks " + how + "d by " + std::to_string(k) + " px",
             {"degrade", study, "--mask-" + how, std::to_string(k), "--out", "@OUT"}, "", {"study/scene"}});
      reconstruct_study(id, "study scene with masks " + how + "d by " + std::to_string(k) + " px", id + "-scene", {}, {});
    }
  for (int n : s.mask_blobs) {
    const std::string id = "study/mask-blobs-" + std::to_string(n);
    p.add({id + "-scene", "study scene, " + std::to_string(n) + " blobs flipped per mask",
           {"degrade", study, "--mask-blobs", std::to_string(n), "--mask-blob-radius", s.blob_radius, "--out", "@OUT"}, "",
           {"study/scene"}});
    reconstruct_study(id, "study scene with " + std::to_string(n) + " blobs flipped per mask", id + "-scene", {}, {});
  }
  for (const auto& it : s.stage1_iterations) {
    reconstruct_study("study/iterations-" + it, "study scene, stage 1 with " + it + " + " + it + " iterations", "study/scene",
                      {"--iterations", it, "--refine-iterations", it}, {});
  }
  for (const auto& b : s.stage1_batches)
    reconstruct_study("study/batch-" + b, "study scene, stage 1 with " + b + " views per iteration", "study/scene",
                      {"--batch", b, "--refine-batch", b}, {});
  // one shape at several true IoRs: a sphere under the study scene's map
  p.add({"ior/sphere", "an icosphere mesh", {"shape", "sphere-5", "--out", "@WORK/ior/sphere/sphere.obj"}, "", {}});
  for (const auto& ior : s.iors) {
    const std::string id = "ior/" + ior;
    p.add({id + "/scene", "synthesize the sphere at IoR " + ior,
           cat({"synth", "--mesh", "@WORK/ior/sphere/sphere.obj", "--ior", ior, "--env",
                "@WORK/study/scene/out/gt/envmap.hdr", "--out", "@OUT"},
               s.study_synth),
           "", {"ior/sphere", "study/scene"}});
    reconstruct_study(id + "/run", "reconstruct the sphere at IoR " + ior, id + "/scene", {}, {});
  }
  return p;
}

// ---- reading the runs back -------------------------------------------------

double at(const io::Json& j, const std::string& pointer) {
  if (j.is_null()) return std::numeric_limits<double>::quiet_NaN();
  const io::Json::json_pointer ptr(pointer);
  if (!j.contains(ptr)) return std::numeric_limits<double>::quiet_NaN();
  const io::Json& v = j.at(ptr);
  return v.is_number() ? v.get<double>() : std::numeric_limits<double>::quiet_NaN();
}

struct Reader {
  const Runner& runner;
  // OUT/reconstruct.json of a reconstruct run, else null
  io::Json reconstruction(const std::string& id) const {
    const fs::path p = runner.out(id) / "reconstruct.json";
    if (!runner.ok(id) || !fs::exists(p)) return nullptr;
    return io::read_json(p);
  }
};

double mean_of(const std::vector<double>& v) {
  double s = 0;
  int n = 0;
  for (double x : v)
    if (std::isfinite(x)) s += x, ++n;
  return n ? s / n : std::numeric_limits<double>::quiet_NaN();
}

// Relative MSE of the linear images of run A against run B, over the pixels
// B's object covers, all views together; NaN when either is missing.
double relative_mse(const Runner& runner, const std::string& a, const std::string& b) {
  if (!runner.ok(a) || !runner.ok(b) || !fs::is_directory(runner.out(b) / "images")) return std::numeric_limits<double>::quiet_NaN();
  double num = 0, den = 0;
  for (const auto& e : fs::directory_iterator(runner.out(b) / "images")) {
    const fs::path pa = runner.out(a) / "images" / e.path().filename();
    const fs::path pm = runner.out(b) / "masks" / (e.path().stem().string() + ".png");
    if (!fs::exists(pa) || !fs::exists(pm)) return std::numeric_limits<double>::quiet_NaN();
    const io::Image ia = io::read_image(pa), ib = io::read_image(e.path());
    const io::Mask m = io::read_mask(pm);
    if (ia.width != ib.width || ia.height != ib.height || m.width != ib.width || m.height != ib.height)
      return std::numeric_limits<double>::quiet_NaN();
    for (std::size_t i = 0; i < ib.pixel_count(); ++i) {
      if (!m.inside[i]) continue;
      for (int c = 0; c < 3; ++c) {
        const double d = double(ia.rgb[3 * i + c]) - double(ib.rgb[3 * i + c]);
        num += d * d;
        den += double(ib.rgb[3 * i + c]) * double(ib.rgb[3 * i + c]);
      }
    }
  }
  return den > 0 ? num / den : std::numeric_limits<double>::quiet_NaN();
}

// Copies a picture of a run into OUT/img/NAME; returns its page path or "".
std::string picture(const Runner& runner, const std::string& id, const std::string& file, const fs::path& out, const std::string& name) {
  const fs::path src = runner.out(id) / file;
  if (!runner.ok(id) || !fs::exists(src)) return "";
  fs::create_directories(out / "img");
  fs::copy_file(src, out / "img" / name, fs::copy_options::overwrite_existing);
  return "img/" + name;
}

// The gradient's time against its error, measured in this process on the
// true object of a scene: reverse-mode gradients of a fixed weighting of one
// view's pixels with respect to every parameter (vertices, IoR, absorption,
// environment texels), at several depths and pruning thresholds in float,
// against the same gradient in double at the training depth (4) without
// pruning. Deeper trees are not compared: past a few interactions the
// derivative of a path is chaotic (docs/stage2-diagnostics.md).
struct GradientPoint {
  std::string what;
  int depth = 4;
  float prune = 0.0f;
  double seconds = 0, error = 0;
};
std::vector<GradientPoint> gradient_sweep(const fs::path& scene_dir, int size, double* reference_seconds) {
  const fs::path gt = scene_dir / "gt";
  render::HostScene s = render::make_host_scene(io::read_mesh(gt / "mesh.obj"), io::read_material(gt / "material.json"), "truth");
  const io::Image env = io::read_image(gt / "envmap.hdr");
  s.set_environment_map(env.rgb, env.width, env.height);
  const scene::Camera cam = scene::protocol_camera(Vec3f(0.4f, 0.5f, 1.0f), size, size);
  std::vector<float> adjoint(std::size_t(size) * std::size_t(size) * 3);
  for (std::size_t i = 0; i < adjoint.size(); ++i) adjoint[i] = 0.5f + 0.5f * std::sin(0.37f * float(i));
  const auto flat = [](const render::SceneGradient& g) {
    std::vector<double> v;
    for (const auto* a : {&g.positions, &g.ior, &g.absorption, &g.environment}) v.insert(v.end(), a->begin(), a->end());
    return v;
  };
  const auto timed = [](auto&& f) {
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 2; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      f();
      best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    return best;
  };
  render::PassOptions ref_opt;
  ref_opt.trace.max_depth = 4;
  render::SceneGradient ref(s);
  *reference_seconds = timed([&] {
    ref = render::SceneGradient(s);
    render::render_gradient<double>(s, cam, adjoint.data(), ref, ref_opt);
  });
  const std::vector<double> want = flat(ref);
  std::vector<GradientPoint> points;
  const auto point = [&](int depth, float prune) {
    render::PassOptions o;
    o.trace.max_depth = depth;
    o.trace.prune_throughput = prune;
    render::SceneGradient g(s);
    GradientPoint p;
    p.depth = depth, p.prune = prune;
    p.what = "depth " + std::to_string(depth) + (prune > 0 ? ", pruned below " + number_text(prune, 2) : "");
    p.seconds = timed([&] {
      g = render::SceneGradient(s);
      render::render_gradient<float>(s, cam, adjoint.data(), g, o);
    });
    const std::vector<double> got = flat(g);
    double num = 0, den = 0;
    for (std::size_t i = 0; i < got.size(); ++i) num += (got[i] - want[i]) * (got[i] - want[i]), den += want[i] * want[i];
    p.error = den > 0 ? std::sqrt(num / den) : std::numeric_limits<double>::quiet_NaN();
    points.push_back(p);
  };
  for (int depth : {1, 2, 3, 4}) point(depth, 0.0f);
  for (float prune : {0.1f, 0.03f, 0.01f}) point(4, prune);
  return points;
}

const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};

std::vector<Section> collect(const Suite& s, const Runner& runner, const fs::path& out) {
  const Reader rd{runner};
  std::vector<Section> sections;
  // a section that cannot be read (a damaged file) says so; the others stand
  const auto guarded = [&sections](const std::string& id, const std::string& title, auto&& make) {
    try {
      sections.push_back(make());
    } catch (const std::exception& e) {
      warn("report: section " + title + " could not be made: " + e.what());
      sections.push_back({id, title, "<b>This section could not be made:</b> " + html_escape(e.what()), {}, {}, {}});
    }
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();

  // 1. geometry
  guarded("geometry", "1. Geometry", [&] {
    Section sec{"geometry", "1. Geometry", "", {}, {}, {}};
    sec.intro = "Chamfer distance (CD, ×1e-4; meshes normalized to a longest side of 1, docs/metrics.md) and F1 after stage 1 "
                "and after stage 2 as the defaults run it (the vertices refined with the IoR and the absorption).";
    Table t{"geometry", "CD and F1 per scene", "", {"scene", "CD stage 1", "CD stage 2", "CD stage 2 / stage 1", "F1 stage 1",
                                                    "F1 stage 2", "normals off, ° stage 1", "normals off, ° stage 2",
                                                    "genus (true / found)"}, {}};
    std::vector<double> c1, c2, f1, f2;
    for (const auto& sc : s.scenes) {
      const io::Json a = rd.reconstruction(sid(sc, "stage2"));
      const io::Json st1 = rd.reconstruction(sid(sc, "stage1"));
      const double cd1 = at(st1, "/geometry/final/chamfer") * 1e4, cd2 = at(a, "/materials/chamfer") * 1e4;
      const double fa = at(st1, "/geometry/final/f1"), fb = at(a, "/materials/f1");
      c1.push_back(cd1), c2.push_back(cd2), f1.push_back(fa), f2.push_back(fb);
      t.rows.push_back({label(sc), number(cd1, 3, sid(sc, "stage1")), number(cd2, 3, sid(sc, "stage2")),
                        number(cd2 / cd1, 3, sid(sc, "stage2")), number(fa, 3, sid(sc, "stage1")), number(fb, 3, sid(sc, "stage2")),
                        number(at(st1, "/geometry/final/normal_error_deg/mean"), 2, sid(sc, "stage1")),
                        number(at(a, "/materials/normal_error_deg/mean"), 2, sid(sc, "stage2")),
                        {number_text(at(st1, "/geometry/gt_genus"), 0) + " / " + number_text(at(st1, "/geometry/final/genus"), 0),
                         at(st1, "/geometry/final/genus"), sid(sc, "stage1")}});
      const std::string pic = picture(runner, sid(sc, "stage2"), "geometry_stage2.png", out, sc + "_geometry.png");
      if (!pic.empty())
        sec.pictures.push_back({pic, sc + ": stage 1 | stage 2 | truth, six sides, coloured by the distance to the true surface"});
    }
    t.rows.push_back({label("mean"), {number_text(mean_of(c1), 3), mean_of(c1), ""}, {number_text(mean_of(c2), 3), mean_of(c2), ""},
                      {number_text(mean_of(c2) / mean_of(c1), 3), mean_of(c2) / mean_of(c1), ""},
                      {number_text(mean_of(f1), 3), mean_of(f1), ""}, {number_text(mean_of(f2), 3), mean_of(f2), ""}, label(""), label(""),
                      label("")});
    t.rows.push_back({{"paper (mean over its scenes)", nan, "paper"}, {"4.67", 4.67, "paper"}, {"3.26", 3.26, "paper"},
                      {number_text(3.26 / 4.67, 3), 3.26 / 4.67, "paper"},
                      {"0.809", 0.809, "paper"}, {"0.839", 0.839, "paper"}, {"", nan, "paper"}, {"", nan, "paper"},
                      {"", nan, "paper"}});
    t.note = "The paper's scenes and their scale are its own; its means are shown for the direction of the change, not the level. "
             "Normals off: the mean angle between the mesh's shading normal and the true surface's at the nearest point "
             "(docs/metrics.md); refraction turns with it, and the IoR fitted on a mesh makes up for it.";
    sec.tables.push_back(t);
    return sec;
  });

  // 2. IoR
  guarded("ior", "2. Index of refraction", [&] {
    Section sec{"ior", "2. Index of refraction", "", {}, {}, {}};
    sec.intro = "The IoR stage 2 finds, against the true one; the paper's value for the same shape beside it.";
    Table t{"ior", "IoR per scene", "", {"scene", "true", "found", "error", "found (vertices held)", "error (vertices held)",
                                         "paper: true", "paper: found"}, {}};
    for (const auto& sc : s.scenes) {
      const io::Json a = rd.reconstruction(sid(sc, "stage2")), b = rd.reconstruction(sid(sc, "materials-only"));
      std::vector<Cell> row{label(sc), number(at(a, "/materials/ior_true"), 3, sid(sc, "stage2")),
                            number(at(a, "/materials/ior"), 4, sid(sc, "stage2")), number(at(a, "/materials/ior_error"), 4, sid(sc, "stage2")),
                            number(at(b, "/materials/ior"), 4, sid(sc, "materials-only")),
                            number(at(b, "/materials/ior_error"), 4, sid(sc, "materials-only"))};
      bool found = false;
      for (const auto& pi : paper_iors)
        if (sc == pi.scene) {
          row.push_back({number_text(pi.truth, 3) + " (" + pi.shape + ")", pi.truth, "paper"});
          row.push_back({number_text(pi.found, 3), pi.found, "paper"});
          found = true;
        }
      if (!found) row.push_back({"", nan, "paper"}), row.push_back({"", nan, "paper"});
      t.rows.push_back(row);
    }
    sec.tables.push_back(t);
    Table sweep{"ior_sweep", "One shape (a sphere) at several true IoRs", "", {"true IoR", "found", "error", "CD stage 1 (×1e-4)"}, {}};
    Plot plot{"ior_sweep_plot", "IoR found against true (sphere)", "true IoR", "found IoR", "", false, false, {}};
    Series found{"found", colours[0], {}, false}, diagonal{"found = true", "#999", {}, true, false};
    for (const auto& ior : s.iors) {
      const std::string id = "ior/" + ior + "/run";
      const io::Json r = rd.reconstruction(id);
      const double truth = std::stod(ior), f = at(r, "/materials/ior");
      sweep.rows.push_back({label(ior), number(f, 4, id), number(at(r, "/materials/ior_error"), 4, id),
                            number(at(r, "/geometry/final/chamfer") * 1e4, 3, id)});
      found.points.push_back({truth, f, "true " + ior + ", found " + number_text(f, 4), id, false});
      diagonal.points.push_back({truth, truth, ior, "", false});
    }
    plot.series = {diagonal, found};
    plot.note = "The paper shows this study as a figure (its \"different IoRs\"), without numbers to set beside these.";
    sec.tables.push_back(sweep);
    sec.plots.push_back(plot);
    return sec;
  });

  // 3. novel views and relighting
  guarded("views", "3. Novel views and relighting", [&] {
    Section sec{"views", "3. Novel views and relighting", "", {}, {}, {}};
    sec.intro = "PSNR (dB, tone-mapped, whole frame and inside the object's mask) and SSIM of the reconstruction on the held-out "
                "test views under the training light, and under every other environment map of the data, against the ground "
                "truth under the same map.";
    Table t{"views", "Held-out views and relighting", "", {"scene", "test PSNR", "test PSNR in mask", "test SSIM", "relit PSNR (mean)",
                                                          "relit PSNR in mask", "relit SSIM", "maps"}, {}};
    std::vector<double> relit;
    for (const auto& sc : s.scenes) {
      const io::Json a = rd.reconstruction(sid(sc, "stage2"));
      const io::Json r = runner.result(sid(sc, "relight"));
      const double maps = r.is_null() || !r.contains("environments") ? nan : double(r["environments"].size());
      relit.push_back(at(r, "/psnr"));
      t.rows.push_back({label(sc), number(at(a, "/materials/test/psnr"), 2, sid(sc, "stage2")),
                        number(at(a, "/materials/test/psnr_mask"), 2, sid(sc, "stage2")),
                        number(at(a, "/materials/test/ssim"), 3, sid(sc, "stage2")), number(at(r, "/psnr"), 2, sid(sc, "relight")),
                        number(at(r, "/psnr_mask"), 2, sid(sc, "relight")), number(at(r, "/ssim"), 3, sid(sc, "relight")),
                        number(maps, 0, sid(sc, "relight"))});
      std::string pic = picture(runner, sid(sc, "stage2"), "stage2_test/contact_sheet.png", out, sc + "_test.png");
      if (!pic.empty()) sec.pictures.push_back({pic, sc + ", test views: truth | reconstruction | error"});
      if (!r.is_null() && r.contains("environments") && !r["environments"].empty()) {
        const std::string folder = r["environments"][0].value("folder", "");
        pic = picture(runner, sid(sc, "relight"), folder + "/contact_sheet.png", out, sc + "_relit.png");
        if (!pic.empty()) sec.pictures.push_back({pic, sc + ", relit under " + folder + ": truth | reconstruction | error"});
      }
    }
    t.rows.push_back({label("mean"), label(""), label(""), label(""), {number_text(mean_of(relit), 2), mean_of(relit), ""}, label(""),
                      label(""), label("")});
    t.rows.push_back({{"paper (relighting, mean)", nan, "paper"}, {"", nan, "paper"}, {"", nan, "paper"}, {"", nan, "paper"},
                      {"23.17", 23.17, "paper"}, {"", nan, "paper"}, {"", nan, "paper"}, {"", nan, "paper"}});
    sec.tables.push_back(t);
    return sec;
  });

  // 4. ablations
  guarded("ablations", "4. Ablations", [&] {
    Section sec{"ablations", "4. Ablations", "", {}, {}, {}};
    sec.intro = "What each part contributes, on the study scene (spot-clear, " + std::string(s.study_synth.size() > 1 ? s.study_synth[1] : "") +
                " variant" + (s.study_stage1.empty() ? "" : ", shortened stage 1") + ") unless said.";
    Table tone{"tone", "The tone term of stage 2's loss", "", {"scene", "run", "IoR error", "test PSNR", "test PSNR in mask", "test SSIM"}, {}};
    const auto tone_row = [&](const std::string& scene, const std::string& what, const std::string& id) {
      const io::Json r = rd.reconstruction(id);
      tone.rows.push_back({label(scene), label(what), number(at(r, "/materials/ior_error"), 4, id), number(at(r, "/materials/test/psnr"), 2, id),
                           number(at(r, "/materials/test/psnr_mask"), 2, id), number(at(r, "/materials/test/ssim"), 3, id)});
    };
    if (s.tone_on_scenes) {
      for (const auto& sc : s.scenes) tone_row(sc, "with tone", sid(sc, "stage2")), tone_row(sc, "without", sid(sc, "tone-off"));
    } else {
      tone_row("study", "with tone", "study/default"), tone_row("study", "without", "study/tone-off");
    }
    sec.tables.push_back(tone);
    Table parts{"stage1_parts", "Stage 1's parts", "", {"run", "CD (×1e-4)", "F1", "genus", "IoR error"}, {}};
    for (const auto& [id, what] : std::vector<std::pair<std::string, std::string>>{{"study/default", "all parts"},
                                                                                  {"study/no-dilation", "no dilation term"},
                                                                                  {"study/no-smoothness", "no smoothness term"},
                                                                                  {"study/no-carving", "no carving"}}) {
      const io::Json r = rd.reconstruction(id);
      parts.rows.push_back({label(what), number(at(r, "/geometry/final/chamfer") * 1e4, 3, id), number(at(r, "/geometry/final/f1"), 3, id),
                            number(at(r, "/geometry/final/genus"), 0, id), number(at(r, "/materials/ior_error"), 4, id)});
    }
    sec.tables.push_back(parts);
    Table noise{"mask_noise", "Imperfect masks", "", {"masks", "CD (×1e-4)", "F1", "IoR error"}, {}};
    Plot np{"mask_noise_plot", "CD against mask noise", "pixels of erosion (−) or dilation (+)", "CD (×1e-4)", "", false, true, {}};
    Series cd{"CD after stage 1", colours[0], {}, true};
    const auto noise_row = [&](const std::string& what, const std::string& id, double level) {
      const io::Json r = rd.reconstruction(id);
      const double c = at(r, "/geometry/final/chamfer") * 1e4;
      noise.rows.push_back({label(what), number(c, 3, id), number(at(r, "/geometry/final/f1"), 3, id),
                            number(at(r, "/materials/ior_error"), 4, id)});
      cd.points.push_back({level, c, what, id, level == 0});
    };
    noise_row("exact", "study/default", 0);
    for (int k : s.mask_noise) {
      noise_row("eroded " + std::to_string(k) + " px", "study/mask-erode-" + std::to_string(k), -k);
      noise_row("dilated " + std::to_string(k) + " px", "study/mask-dilate-" + std::to_string(k), k);
    }
    for (int n : s.mask_blobs)
      noise_row(std::to_string(n) + " blobs of " + s.blob_radius + " px flipped", "study/mask-blobs-" + std::to_string(n), nan);
    noise.note = "Masks eroded or dilated by a disk, or with random discs near the object flipped inside-out "
                 "(difftrans degrade --mask-erode, --mask-dilate, --mask-blobs); the plot shows erosion and dilation. "
                 "One pixel spans 2 · 3 · tan 20° / width scene units at the protocol's cameras (0.034 at 64², where "
                 "the object is about 29 pixels across): a shape grown by one pixel has a CD near 2 · 0.034² = 23 ×1e-4.";
    np.series = {cd};
    sec.tables.push_back(noise);
    sec.plots.push_back(np);
    return sec;
  });

  // 5. speed against error
  guarded("speed", "5. Speed against error", [&] {
    Section sec{"speed", "5. Speed against error", "", {}, {}, {}};
    sec.intro = "Render time per view (tracing only, " + std::to_string(s.speed_resolution) + "², the true spot-clear object) against "
                "the relative squared error of its linear radiance over the object's pixels (Σ(x − x_ref)² / Σ x_ref², all views), "
                "against a converged render (depth " +
                std::to_string(s.reference_depth) + ", " + std::to_string(s.reference_spp_axis * s.reference_spp_axis) +
                " samples per pixel). Ringed: the render command's defaults (depth 16, 4×4 samples, no roulette). "
                "The black line joins the settings no other setting beats in both.";
    Plot plot{"speed_render", "Render time per view against image error", "seconds per view", "relative squared error", "", true, true,
              {}};
    Table t{"speed_render", "Render settings", "", {"depth", "samples per pixel", "roulette", "seconds per view", "relative squared error",
                                                    "Pareto"}, {}};
    struct P {
      double sec, err;
      std::string id, what;
    };
    std::vector<P> all;
    int k = 0;
    for (const auto& r : s.roulettes) {
      Series ser{"roulette " + r, colours[k++ % 6], {}, false};
      for (int d : s.depths)
        for (int n : s.spp_axes) {
          const std::string id = "speed/d" + std::to_string(d) + "-s" + std::to_string(n) + "-r" + r;
          const double sec_view = at(runner.result(id), "/trace/seconds_per_view");
          const double err = relative_mse(runner, id, "speed/reference");
          const std::string what = "depth " + std::to_string(d) + ", " + std::to_string(n * n) + " spp";
          ser.points.push_back({sec_view, err, what + ": " + number_text(sec_view, 3) + " s, " + sci_text(err, 2), id,
                                d == 16 && n == 4 && r == "0"});
          all.push_back({sec_view, err, id, what + ", roulette " + r});
        }
      plot.series.push_back(ser);
    }
    Series front{"Pareto front", "#000", {}, true, false};
    std::set<std::string> on_front;
    for (const auto& a : all) {
      if (!std::isfinite(a.sec) || !std::isfinite(a.err)) continue;
      bool dominated = false;
      for (const auto& b : all)
        if (std::isfinite(b.sec) && std::isfinite(b.err) && b.sec <= a.sec && b.err <= a.err && (b.sec < a.sec || b.err < a.err))
          dominated = true;
      if (!dominated) front.points.push_back({a.sec, a.err, a.what, a.id, false}), on_front.insert(a.id);
    }
    plot.series.insert(plot.series.begin(), front);
    for (const auto& r : s.roulettes)
      for (int d : s.depths)
        for (int n : s.spp_axes) {
          const std::string id = "speed/d" + std::to_string(d) + "-s" + std::to_string(n) + "-r" + r;
          const P* pt = nullptr;
          for (const auto& a : all)
            if (a.id == id) pt = &a;
          t.rows.push_back({label(std::to_string(d)), label(std::to_string(n * n)), label(r), number(pt->sec, 4, id), sci(pt->err, 2, id),
                            label(on_front.count(id) ? "yes" : "")});
        }
    sec.plots.push_back(plot);
    sec.tables.push_back(t);
    // the gradient, in this process
    {
      const std::string scene_id = sid(s.scenes.front(), "scene");
      Plot gp{"speed_gradient", "Gradient time against gradient error", "seconds per gradient (one view)", "relative L2 error",
              "", true, true, {}};
      Table gt{"speed_gradient", "Gradient settings", "", {"setting", "seconds", "relative L2 error"}, {}};
      if (runner.ok(scene_id)) {
        double ref_seconds = 0;
        const auto pts = gradient_sweep(runner.out(scene_id), s.gradient_size, &ref_seconds);
        Series depth{"depth", colours[0], {}, false}, pruned{"depth 4, pruned", colours[1], {}, false};
        for (const auto& q : pts) {
          (q.prune > 0 ? pruned : depth).points.push_back({q.seconds, q.error, q.what, "", q.depth == 4 && q.prune == 0});
          gt.rows.push_back({label(q.what), {number_text(q.seconds, 4), q.seconds, ""}, {sci_text(q.error, 2), q.error, ""}});
        }
        gt.rows.push_back({label("reference: double, depth 4"), {number_text(ref_seconds, 4), ref_seconds, ""}, label("0")});
        gp.series = {depth, pruned};
        gp.note = "The true " + s.scenes.front() + " object, one " + std::to_string(s.gradient_size) + "² view, measured in the "
                  "report's own process (best of two). Error: relative L2 distance of the whole gradient (vertices, IoR, absorption, "
                  "environment texels) from the double-precision gradient at depth 4, the training depth; ringed: float at depth 4, "
                  "what stage 2 trains with before pruning.";
      }
      sec.plots.push_back(gp);
      sec.tables.push_back(gt);
    }
    Plot rec{"speed_reconstruction", "Reconstruction wall time against CD (study scene: stage-1 iterations and views per iteration)", "wall seconds",
             "CD after stage 1 (×1e-4)", "", true, true, {}};
    Series pts{"stage-1 iterations", colours[0], {}, true};
    std::vector<std::string> ids{"study/default"};
    for (const auto& it : s.stage1_iterations) ids.push_back("study/iterations-" + it);
    for (const auto& id : ids) {
      const std::string it = id == "study/default" ? "the study's" : id.substr(id.rfind('-') + 1) + " + " + id.substr(id.rfind('-') + 1);
      const JobRecord* jr = runner.record(id);
      pts.points.push_back({jr && jr->status == "done" ? jr->wall_seconds : nan,
                            at(rd.reconstruction(id), "/geometry/final/chamfer") * 1e4, it + " iterations", id, id == "study/default"});
    }
    Series batch{"stage-1 views per iteration", colours[1], {}, true};
    for (const auto& b : s.stage1_batches) {
      const std::string id = "study/batch-" + b;
      const JobRecord* jr = runner.record(id);
      batch.points.push_back({jr && jr->status == "done" ? jr->wall_seconds : nan,
                              at(rd.reconstruction(id), "/geometry/final/chamfer") * 1e4, b + " views per iteration", id, false});
    }
    if (!s.stage1_batches.empty()) {  // the default, 8, is the ringed point of the first series
      const JobRecord* jr = runner.record("study/default");
      batch.points.push_back({jr && jr->status == "done" ? jr->wall_seconds : nan,
                              at(rd.reconstruction("study/default"), "/geometry/final/chamfer") * 1e4, "8 views per iteration", "study/default", false});
    }
    rec.series = {pts, batch};
    rec.note = "Wall time of the whole run (environment, stage 1, stage 2); blue: stage 1's iteration counts, red: the training "
               "views (and so the rays) stage 1 renders per iteration (8 by default). Ringed: the study's own settings.";
    sec.plots.push_back(rec);
    return sec;
  });

  // 6. numerical stability: the hard cases the tests assert on, counted here
  guarded("stability", "6. Numerical stability", [&] {
    Section sec{"stability", "6. Numerical stability", "", {}, {}, {}};
    sec.intro = "The hard cases of <code>render/hard_cases.hpp</code> (the list <code>tests/render/tracer.test.cpp</code> "
                "asserts to be clean), traced here by the same code: radiance in float and in double, and the reverse-mode "
                "gradient (double) with respect to every parameter of the scene (vertices, IoR, absorption, environment "
                "texels). Counted in this process, not by a run.";
    Table t{"stability", "Values and gradients that are not finite", "", {"case", "depth", "rays", "values not finite", "values below 0",
                                                                        "gradient entries not finite", "tape overflows"}, {}};
    for (int depth : {8, 16}) {
      render::TraceSettings ts;
      ts.max_depth = depth;
      for (const auto& c : render::hard_cases()) {
        const render::HardCaseResult r = render::check_hard_case(c, ts);
        const auto of = [](std::int64_t bad, std::int64_t all) {
          return Cell{std::to_string(bad) + " / " + std::to_string(all), double(bad), ""};
        };
        t.rows.push_back({label(c.name), label(std::to_string(depth)), label(std::to_string(r.rays)), of(r.nonfinite_values, r.values),
                          of(r.negative_values, r.values), of(r.nonfinite_gradients, r.gradients),
                          {std::to_string(r.tape_overflows), double(r.tape_overflows), ""}});
      }
    }
    t.note = "Depth 8 is the test's; 16 the render command's default.";
    sec.tables.push_back(t);
    return sec;
  });

  // 7. cost
  guarded("cost", "7. Cost", [&] {
    Section sec{"cost", "7. Cost", "", {}, {}, {}};
    sec.intro = "Wall time, CPU time and peak memory per reconstruction, and its stages' own timings from reconstruct.json.";
    Table t{"cost", "Per scene", "", {"scene", "stage 1 run: wall s", "stage 1 run: CPU s", "stage 1 run: peak MB", "environment s",
                                      "geometry s", "stage 2 run: wall s", "stage 2 run: CPU s", "stage 2 run: peak MB",
                                      "materials fit s", "absorption choice s"}, {}};
    for (const auto& sc : s.scenes) {
      const JobRecord* a = runner.record(sid(sc, "stage1"));
      const JobRecord* b = runner.record(sid(sc, "stage2"));
      const io::Json ra = rd.reconstruction(sid(sc, "stage1")), rb = rd.reconstruction(sid(sc, "stage2"));
      const auto w = [](const JobRecord* r, double JobRecord::*f) { return r && r->status == "done" ? r->*f : std::numeric_limits<double>::quiet_NaN(); };
      t.rows.push_back({label(sc), number(w(a, &JobRecord::wall_seconds), 1, sid(sc, "stage1")),
                        number(w(a, &JobRecord::cpu_seconds), 1, sid(sc, "stage1")), number(w(a, &JobRecord::peak_memory_mb), 0, sid(sc, "stage1")),
                        number(at(ra, "/environment/fit_seconds") +
                                   (std::isfinite(at(ra, "/environment/choice/seconds")) ? at(ra, "/environment/choice/seconds") : 0.0),
                               1, sid(sc, "stage1")),
                        number(at(ra, "/geometry/seconds"), 1, sid(sc, "stage1")), number(w(b, &JobRecord::wall_seconds), 1, sid(sc, "stage2")),
                        number(w(b, &JobRecord::cpu_seconds), 1, sid(sc, "stage2")), number(w(b, &JobRecord::peak_memory_mb), 0, sid(sc, "stage2")),
                        number(at(rb, "/materials/fit_seconds"), 1, sid(sc, "stage2")),
                        number(at(rb, "/materials/absorption_model/seconds"), 1, sid(sc, "stage2"))});
    }
    t.note = "Environment: the model choice plus the fit. The whole suite's runs, one by one, are listed under Runs.";
    sec.tables.push_back(t);
    Table tr{"throughput", "Tracing throughput (the speed renders of section 5)", "", {"render", "camera rays per second",
                                                                                       "ray segments per second", "segments per camera ray"}, {}};
    for (const auto& [id, what] : std::vector<std::pair<std::string, std::string>>{
             {"speed/d16-s4-r0", "the render command's defaults (depth 16, 4×4 samples)"},
             {"speed/d16-s4-r0.01", "the same with roulette below 0.01"},
             {"speed/reference", "the converged reference"}}) {
      const io::Json r = runner.result(id);
      if (r.is_null()) continue;
      const double trace_s = at(r, "/trace/seconds"), rays = at(r, "/trace/camera_rays"), segs = at(r, "/trace/segments");
      tr.rows.push_back({label(what), sci(rays / trace_s, 3, id), sci(segs / trace_s, 3, id), number(segs / rays, 2, id)});
    }
    tr.note = "Threads per run as in the footer; the tracer's own seconds (no image writing).";
    sec.tables.push_back(tr);
    return sec;
  });
  return sections;
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("model name", 0) == 0) {
      const auto p = line.find(':');
      return p == std::string::npos ? line : line.substr(p + 2);
    }
  return "unknown";
}

struct ReportOptions {
  std::string suite = "quick";
  std::string out = "report";
  std::string work;
  bool rerun = false;
  bool list = false;
};

void run_report(const ReportOptions& o) {
  const Suite suite = make_suite(o.suite);
  const fs::path out = fs::absolute(o.out);
  const fs::path work = o.work.empty() ? out / "runs" : fs::absolute(o.work);
  Runner runner(work, o.rerun);
  const Plan plan = make_plan(suite);
  if (o.list) {  // the plan alone: what would run, from the work folder
    io::Json runs = io::Json::array();
    for (const auto& j : plan.jobs) runs.push_back({{"id", j.id}, {"title", j.title}, {"command", runner.command_line(j)}});
    emit_json({{"suite", o.suite}, {"work", work.string()}, {"runs", runs}}, std::nullopt);
    return;
  }
  progress("report: " + o.suite + " suite, " + std::to_string(plan.jobs.size()) + " runs in " + work.string());
  {
    StopSignals signals;  // only while the runs go: a stop then ends the run going, and the report
    runner.run_all(plan.jobs);
  }
  const std::vector<Section> sections = collect(suite, runner, out);
  const std::time_t now = std::time(nullptr);
  char when[64];
  std::strftime(when, sizeof when, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  const char* threads = std::getenv("DIFFTRANS_THREADS");
  PageInfo info;
  info.suite = o.suite;
  info.generated = when;
  info.machine = {{"cpu", cpu_model()},
                  {"cores", std::thread::hardware_concurrency()},
                  {"threads", threads ? std::string(threads) : std::string("all cores")},
                  {"compiler", __VERSION__},
                  {"flags", DIFFTRANS_BUILD_FLAGS}};
  info.machine_html = "<p class=\"note\">CPU: " + html_escape(cpu_model()) + ", " + std::to_string(std::thread::hardware_concurrency()) +
                      " cores; threads per run: " + html_escape(threads ? threads : "all cores (DIFFTRANS_THREADS unset)") +
                      ". Compiler: " + html_escape(__VERSION__) + "; flags: <code>" + html_escape(DIFFTRANS_BUILD_FLAGS) +
                      "</code>; build " + html_escape(runner.build()) + ".</p>";
  write_page(out, sections, runner, plan.jobs, info);
  int failed = 0;
  for (const auto& [id, r] : runner.records()) failed += r.status != "done";
  progress("report: wrote " + (out / "index.html").string() + " (" + std::to_string(plan.jobs.size() - std::size_t(failed)) + " of " +
           std::to_string(plan.jobs.size()) + " runs finished)");
  emit_json({{"index", (out / "index.html").string()}, {"results", (out / "results.json").string()}, {"runs", plan.jobs.size()},
             {"failed_or_skipped", failed}},
            std::nullopt);
  if (failed) throw std::runtime_error("report: " + std::to_string(failed) + " run(s) failed or were skipped (see the page's Runs)");
}

}  // namespace

void add_report(CLI::App& app) {
  auto o = std::make_shared<ReportOptions>();
  CLI::App* cmd = app.add_subcommand("report", "Run a suite of experiments and write a benchmark page (HTML, JSON, CSV)");
  cmd->footer(
      "Runs the suite's difftrans commands one after another, each in WORK/ID (default WORK: OUT/runs), then writes\n"
      "OUT/index.html (tables, SVG plots, pictures; every number links to the run behind it), OUT/results.json and\n"
      "OUT/TABLE.csv. A run whose inputs (its command and the runs it reads) are unchanged and that finished is\n"
      "reused: after a stop, the same command goes on where it stopped (--rerun makes every run again, e.g. after\n"
      "rebuilding with a change that alters results; the page marks runs made by another build).\n"
      "Suites: tiny (seconds to a minute; the test), quick (4 quick scenes at 128^2, about an hour on 2 cores),\n"
      "full (256^2, 100 + 20 views, as the paper; hours). DIFFTRANS_THREADS sets the threads of every run.\n"
      "Example: difftrans report --suite quick --out report");
  cmd->add_option("--suite", o->suite, "tiny, quick or full")->capture_default_str()->check(CLI::IsMember({"tiny", "quick", "full"}));
  cmd->add_option("--out", o->out, "folder of the page")->capture_default_str();
  cmd->add_option("--work", o->work, "folder of the runs (default: OUT/runs)");
  cmd->add_flag("--rerun", o->rerun, "make every run again instead of reusing finished ones");
  cmd->add_flag("--list", o->list, "print the suite's runs and their commands (JSON) and stop");
  cmd->callback([o] { run_report(*o); });
}

}  // namespace difftrans::cli
