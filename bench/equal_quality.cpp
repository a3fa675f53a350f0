// Time per view at equal image quality: today's reference settings (depth 16,
// the whole Fresnel tree, uniform n × n samples) against the faster settings,
// each swept over its sample budget, on one scene. Quality is the PSNR of the
// 8-bit tone-mapped image over the object's pixels (docs/conventions.md)
// against a converged render (uniform 27 × 27, depth 16, no pruning). For
// each target PSNR the time of every setting is read off its curve (linear in
// log time between the two points around the target) and divided into the
// reference settings' time: the speed-up at that quality, measured in one run.
//
// Settings:
//   reference   depth 16, no pruning, uniform n × n, n = 1, 2, 4, 8, 16
//   roulette    the same with Russian roulette below throughput 0.01
//   adaptive    roulette + adaptive sampling (render/adaptive.hpp): rounds
//               of 2 × 2 samples, 2 to 64 per pixel, while the tone-mapped
//               pixel is uncertain, tolerance 64 ... 2 levels
//   roulette+path  roulette, with the Fresnel tree for the first 2
//               interactions and one branch sampled by Fresnel weight beyond
//   adaptive+path  adaptive, the same
//   levels      roulette, n x n samples everywhere, then m x m more in the
//               pixels whose samples spread by more than a tolerance (8-bit
//               tone-mapped levels) and in their neighbours, and so on
//               (render/adaptive.hpp, render_image_levels; --levels below)
//   footprints  roulette, each sample reading the environment averaged over
//               its stratum's footprint (render/footprint.hpp); with
//               --footprint-angles A1,A2,... one curve per largest angle
//
// usage: equal_quality [--mesh spot] [--ior 1.472] [--env venice_sunset_1k.hdr]
//                      [--size 128] [--targets 23,28,33] [--out DIR]
//        equal_quality --scene DIR [--view K] ...   a scene's test view K with
//                      its gt/ mesh, material (IoR, absorption) and map
//        --roulette T1,T2,...   more roulette curves at these thresholds
//        --converged N          the converged render's N × N samples (27)
//        --footprint-angles A1,A2,...   footprint curves with these largest
//                               footprint edges (radians; default 0.3)
//        --levels G/T/D[/R],... levels points: grids G (2-8: 2 x 2, then
//                               8 x 8; 2-8-24: three levels), tolerance T
//                               levels (0 < T < 255), dilation D, roulette below R (0.01);
//                               one curve per all but the last grid and
//                               T/D/R (default 2-m/32/1, m = 6, 8, 10;
//                               2-8-m/64/1, m = 16, 32; 4-16-48/64/1)
//        --only C1,C2,...       run only these curves (and the reference);
//                               a name matches itself and "NAME ..." curves
//        --device cuda          the uniform curves traced on the GPU (the
//                               time of a view: its launches and the image
//                               read back); the adaptive ones need the host
// Each point also says how much of its error the worst 5 % of the object's
// pixels carry (error_profile). Writes equal_quality.json into --out.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "difftrans/io/dataset.hpp"
#include "difftrans/io/hdr.hpp"
#include "difftrans/io/image_file.hpp"
#include "difftrans/io/material.hpp"
#include "difftrans/io/image.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/render/adaptive.hpp"
#include "difftrans/render/footprint.hpp"
#include "difftrans/render/passes.hpp"
#include "difftrans/render/views.hpp"
#include "difftrans/metrics/image.hpp"
#include "support/timing.hpp"
#include "gpu_views.hpp"

namespace dr = difftrans::render;
using difftrans::Vec3f;

namespace {

struct ErrorProfile {
  double worst_share = 0.0, psnr_without_worst = 0.0;
};

struct Point {
  std::string budget;
  double seconds = 0, psnr = 0, samples = 0;
  double psnr_image = 0;  // the whole image's, background too
  ErrorProfile worst;  // error_profile at 5 % of the pixels
};

struct Curve {
  std::string name, description;
  std::vector<Point> points;
};

// Where the error of an image lies: the share of the squared tone-mapped
// error (all channels of a pixel together) that the worst `fraction` of the
// object's pixels carry, and the PSNR the image would have were those pixels
// exact. A large share says that more samples in a few pixels could buy what
// more samples everywhere buy (an upper bound: it knows the converged image).
ErrorProfile error_profile(const std::vector<std::uint8_t>& img8, const std::vector<std::uint8_t>& converged8,
                           const difftrans::io::Mask& mask, double fraction) {
  std::vector<double> err;
  for (std::size_t p = 0; p < mask.inside.size(); ++p) {
    if (!mask.inside[p]) continue;
    double e = 0.0;
    for (std::size_t c = 0; c < 3; ++c) {
      const double d = double(img8[3 * p + c]) - double(converged8[3 * p + c]);
      e += d * d;
    }
    err.push_back(e);
  }
  ErrorProfile r;
  if (err.empty()) return r;
  std::sort(err.begin(), err.end(), std::greater<double>());
  const std::size_t worst = std::size_t(std::ceil(fraction * double(err.size())));
  double total = 0.0, top = 0.0;
  for (std::size_t i = 0; i < err.size(); ++i) (i < worst ? top : total) += err[i];
  total += top;
  r.worst_share = total > 0.0 ? top / total : 0.0;
  const double mse = (total - top) / double(3 * err.size());
  r.psnr_without_worst = mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : std::numeric_limits<double>::infinity();
  return r;
}

// A point's quality, from one tone-mapped copy of its image: the PSNR over the
// object's pixels against the tone-mapped converged render, where that error
// lies (the worst 5 % of the object's pixels), and the whole image's PSNR
// (background too)
void score(Point& pt, const std::vector<float>& img, const std::vector<std::uint8_t>& converged8,
           const difftrans::io::Mask& mask) {
  difftrans::io::Image image(mask.width, mask.height);
  image.rgb = img;
  const std::vector<std::uint8_t> img8 = difftrans::io::tone_map(image);
  const difftrans::metrics::Image8View mine{img8.data(), mask.width, mask.height},
      converged{converged8.data(), mask.width, mask.height};
  pt.psnr = difftrans::metrics::psnr(mine, converged, &mask);
  pt.worst = error_profile(img8, converged8, mask, 0.05);
  pt.psnr_image = difftrans::metrics::psnr(mine, converged);
}

// The time a curve needs to reach `target` dB: linear in log time between the
// last point below and the first point at or above it; < 0: not reached.
double seconds_at(const Curve& c, double target) {
  std::vector<Point> pts = c.points;
  std::sort(pts.begin(), pts.end(), [](const Point& a, const Point& b) { return a.seconds < b.seconds; });
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (pts[i].psnr < target) continue;
    if (i == 0) return pts[0].seconds;  // the cheapest point already reaches it
    const Point &a = pts[i - 1], &b = pts[i];
    if (a.psnr >= target || b.psnr <= a.psnr) return b.seconds;
    const double t = (target - a.psnr) / (b.psnr - a.psnr);
    return std::exp(std::log(a.seconds) + t * (std::log(b.seconds) - std::log(a.seconds)));
  }
  return -1.0;
}

std::vector<double> parse_list(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) v.push_back(std::atof(item.c_str()));
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  std::string mesh_name = "spot", env_name = "venice_sunset_1k.hdr", out_dir = ".", targets_text = "23,28,33",
              scene_dir, roulette_text, device = "cpu",
              footprint_text = "0.3", only_text;
  int converged_per_axis = 27;
  // --levels points: GRIDS/tolerance/dilation[/roulette], GRIDS as 2-8 or 2-8-24
  struct LevelSpec {
    std::vector<int> grids;
    float tolerance = 32.0f;
    int dilate = 1;
    float roulette = 0.01f;
    std::string text;
  };
  std::vector<LevelSpec> level_specs;
  std::string levels_text = "2-6/32/1,2-8/32/1,2-10/32/1,2-8-16/64/1,2-8-32/64/1,4-16-48/64/1";
  float ior = 1.472f;
  int size = 128, view = 0;
  const auto usage = [](std::FILE* to) {
    std::fprintf(to,
                 "usage: equal_quality [--mesh spot] [--ior 1.472] "
                 "[--env venice_sunset_1k.hdr] [--size 128] [--targets 23,28,33] [--scene DIR] [--view K] "
                 "[--roulette T1,T2] [--footprint-angles A1,A2] [--converged N] [--only C1,C2] [--levels G/T/D[/R],...] "
                 "[--device cpu|cuda] [--out DIR]\n"
                 "(the settings and the options: the comment at the top of bench/equal_quality.cpp)\n");
  };
  for (int i = 1; i < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    }
    if (i + 1 == argc) {  // every option takes a value
      std::fprintf(stderr, "equal_quality: %s needs a value\n", a.c_str());
      usage(stderr);
      return 2;
    }
    if (a == "--mesh") mesh_name = argv[i + 1];
    else if (a == "--ior") ior = float(std::atof(argv[i + 1]));
    else if (a == "--env") env_name = argv[i + 1];
    else if (a == "--size") size = std::atoi(argv[i + 1]);
    else if (a == "--targets") targets_text = argv[i + 1];
    else if (a == "--out") out_dir = argv[i + 1];
    else if (a == "--scene") scene_dir = argv[i + 1];
    else if (a == "--view") view = std::atoi(argv[i + 1]);
    else if (a == "--roulette") roulette_text = argv[i + 1];
    else if (a == "--device") device = argv[i + 1];
    else if (a == "--footprint-angles") footprint_text = argv[i + 1];
    else if (a == "--converged") converged_per_axis = std::atoi(argv[i + 1]);
    else if (a == "--only") only_text = argv[i + 1];
    else if (a == "--levels") levels_text = argv[i + 1];
    else {
      std::fprintf(stderr, "equal_quality: unknown option %s\n", a.c_str());
      usage(stderr);
      return 2;
    }
  }
  {
    std::stringstream list(levels_text);
    for (std::string item; std::getline(list, item, ',');) {
      LevelSpec spec;
      spec.text = item;
      std::vector<std::string> parts;
      std::stringstream fields(item);
      for (std::string f; std::getline(fields, f, '/');) parts.push_back(f);
      bool ok = parts.size() == 3 || parts.size() == 4;
      if (ok) {
        std::stringstream grids(parts[0]);
        for (std::string g; std::getline(grids, g, '-');) spec.grids.push_back(std::atoi(g.c_str()));
        spec.tolerance = float(std::atof(parts[1].c_str()));
        spec.dilate = std::atoi(parts[2].c_str());
        if (parts.size() == 4) spec.roulette = float(std::atof(parts[3].c_str()));
        // two 8-bit values differ by 255 at most: a tolerance of 255 or more
        // would mark no pixel, and the run would be its first grid alone
        ok = !spec.grids.empty() && spec.dilate >= 0 && spec.tolerance > 0.0f && spec.tolerance < 255.0f &&
             spec.roulette >= 0.0f && spec.roulette <= 1.0f;
        for (int g : spec.grids) ok = ok && g >= 1;
      }
      ok = ok && spec.grids.front() >= 2;  // one sample per pixel shows no spread
      if (!ok) {
        std::fprintf(stderr,
                     "equal_quality: --levels %s: expected GRIDS/TOLERANCE/DILATION[/ROULETTE], the first grid at "
                     "least 2, the tolerance above 0 and below 255 levels, e.g. 2-8/32/1 or 2-8-24/32/1/0.03\n",
                     item.c_str());
        return 2;
      }
      level_specs.push_back(spec);
    }
  }
  if (device != "cpu" && device != "cuda") {
    std::fprintf(stderr, "equal_quality: --device %s: expected cpu or cuda\n", device.c_str());
    return 2;
  }
  if (device == "cuda" && !difftrans::cli::gpu_unavailable_reason().empty()) {
    std::fprintf(stderr, "equal_quality: --device cuda: %s\n", difftrans::cli::gpu_unavailable_reason().c_str());
    return 77;
  }
  const std::string data = DIFFTRANS_DATA_DIR;
  dr::HostScene s = [&] {
    if (!scene_dir.empty()) {  // the scene's ground truth
      const difftrans::io::Scene scene = difftrans::io::load_scene(scene_dir);
      if (scene.gt.mesh.empty() || scene.gt.material.empty() || scene.gt.envmap.empty() || scene.test.frames.empty()) {
        std::fprintf(stderr, "equal_quality: %s needs gt/mesh.obj, gt/material.json, gt/envmap.hdr and test views\n",
                     scene_dir.c_str());
        std::exit(2);
      }
      dr::HostScene hs = dr::make_host_scene(difftrans::io::read_mesh(scene.gt.mesh),
                                             difftrans::io::read_material(scene.gt.material), "gt");
      dr::set_environment(hs, difftrans::io::read_image(scene.gt.envmap));
      mesh_name = scene_dir;
      env_name = scene.gt.envmap.filename().string();
      ior = hs.ior;
      return hs;
    }
    difftrans::io::Mesh m = difftrans::io::read_mesh(data + "/meshes/" + mesh_name + ".obj");
    difftrans::io::normalize_to_unit_box(m);
    dr::HostScene hs = dr::make_host_scene(m, difftrans::io::Material{}, mesh_name);
    hs.ior = ior;
    dr::set_environment(hs, difftrans::io::read_hdr(data + "/envmaps/" + env_name));
    return hs;
  }();
  const difftrans::scene::Camera cam = [&] {
    if (scene_dir.empty()) return difftrans::scene::protocol_camera(Vec3f(0.4f, 0.5f, 1.0f), size, size);
    const difftrans::io::Scene scene = difftrans::io::load_scene(scene_dir);
    const auto& frames = scene.test.frames;
    return dr::camera_of(frames[std::size_t(std::clamp(view, 0, int(frames.size()) - 1))]);
  }();
  size = cam.width;
  const difftrans::io::Mask mask = dr::object_mask(s, cam);
  const int threads = difftrans::ThreadPool::global().size();
  std::fprintf(stderr, "equal_quality: %s (IoR %.3f) under %s, %d x %d (the object on %.1f %% of the pixels), %d threads, device %s\n",
               mesh_name.c_str(), ior, env_name.c_str(), cam.width, cam.height,
               100.0 * double(mask.count()) / double(cam.width * cam.height), threads, device.c_str());

  dr::PassOptions reference;
  reference.trace.max_depth = 16;
  reference.trace.prune_throughput = 0.0f;
  std::vector<float> converged;
  {
    dr::PassOptions o = reference;
    o.samples_per_axis = converged_per_axis;
    const double sec = dt_bench::best_seconds([&] { converged = dr::render_image<float>(s, cam, o); });
    std::fprintf(stderr, "converged render (%d x %d, depth 16, no pruning): %.1f s\n", converged_per_axis,
                 converged_per_axis, sec);
  }
  difftrans::io::Image converged_image(cam.width, cam.height);
  converged_image.rgb = converged;
  const std::vector<std::uint8_t> converged8 = difftrans::io::tone_map(converged_image);

  std::unique_ptr<difftrans::cli::GpuViewTracer> gpu;
  if (device == "cuda") gpu = std::make_unique<difftrans::cli::GpuViewTracer>(s);
  // one view with options o, on the host or the GPU
  const auto render_view = [&](const dr::PassOptions& o) {
    return gpu ? gpu->render(cam, o, nullptr) : dr::render_image<float>(s, cam, o);
  };
  std::vector<Curve> curves;
  // --only: the curves to run (the reference always runs: the others' speed-ups are against it)
  const auto wanted = [&](const std::string& name) {
    if (only_text.empty() || name == "reference") return true;
    std::stringstream ss(only_text);
    for (std::string item; std::getline(ss, item, ',');)
      if (item == name || name.rfind(item + " ", 0) == 0) return true;
    return false;
  };
  // footprints: the host's footprint pass with these settings
  const auto uniform_curve = [&](const std::string& name, const std::string& what, const dr::PassOptions& base,
                                 const dr::FootprintSettings* footprints = nullptr) {
    if (!wanted(name)) return;
    Curve c{name, what, {}};
    for (int n : {1, 2, 4, 8, 16}) {
      dr::PassOptions o = base;
      o.samples_per_axis = n;
      std::vector<float> img;
      Point pt;
      pt.budget = std::to_string(n) + "x" + std::to_string(n);
      if (gpu) img = render_view(o);  // the first launch of a setting warms up
      pt.seconds = dt_bench::best_seconds([&] {
        img = footprints ? dr::render_image_footprints(s, cam, o, *footprints) : render_view(o);
      });
      score(pt, img, converged8, mask);
      pt.samples = double(n * n);
      std::fprintf(stderr,
                   "  %-14s %-8s %9.4f s  %6.2f dB (image %6.2f)  (worst 5 %% of the object's pixels: %4.1f %% of the "
                   "error; %6.2f dB without)\n",
                   name.c_str(), pt.budget.c_str(), pt.seconds, pt.psnr, pt.psnr_image, 100.0 * pt.worst.worst_share,
                   pt.worst.psnr_without_worst);
      c.points.push_back(pt);
    }
    curves.push_back(c);
  };
  const auto adaptive_curve = [&](const std::string& name, const std::string& what, const dr::PassOptions& base) {
    if (!wanted(name)) return;
    Curve c{name, what, {}};
    for (float tol : {64.0f, 32.0f, 16.0f, 8.0f, 4.0f, 2.0f}) {
      dr::AdaptiveOptions a;
      a.per_axis = 2;
      a.min_rounds = 2;
      a.max_rounds = 64;
      a.tolerance = tol;
      dr::AdaptiveStats st;
      std::vector<float> img;
      Point pt;
      char buf[32];
      std::snprintf(buf, sizeof buf, "tol %g", double(tol));
      pt.budget = buf;
      pt.seconds = dt_bench::best_seconds([&] { img = dr::render_image_adaptive(s, cam, base, a, &st); });
      score(pt, img, converged8, mask);
      pt.samples = st.mean_samples;
      std::fprintf(stderr, "  %-14s %-8s %9.4f s  %6.2f dB (image %6.2f)  %.1f samples per pixel\n", name.c_str(),
                   pt.budget.c_str(), pt.seconds, pt.psnr, pt.psnr_image, pt.samples);
      c.points.push_back(pt);
    }
    curves.push_back(c);
  };

  // levels of uniform grids (render/adaptive.hpp): one point per spec
  const auto levels_curve = [&](const std::string& name, const std::string& what, const dr::PassOptions& base,
                                const std::vector<LevelSpec>& points) {
    if (!wanted(name)) return;
    Curve c{name, what, {}};
    for (const LevelSpec& q : points) {
      dr::LevelOptions l;
      l.per_axis = q.grids;
      l.tolerance = q.tolerance;
      l.dilate = q.dilate;
      dr::LevelStats st;
      std::vector<float> img;
      Point pt;
      pt.budget = q.text;
      pt.seconds = dt_bench::best_seconds([&] { img = dr::render_image_levels(s, cam, base, l, &st); });
      score(pt, img, converged8, mask);
      pt.samples = st.mean_samples;
      // per level: the pixels traced, and (but for the last) how many of them spread
      std::string traced;
      for (std::size_t k = 0; k < st.traced.size(); ++k)
        traced += (k ? ", " : "") + std::to_string(st.traced[k]) +
                  (k < st.spread.size() ? " (" + std::to_string(st.spread[k]) + " spread)" : std::string());
      std::fprintf(stderr, "  %-14s %-18s %9.4f s  %6.2f dB (image %6.2f)  %.1f samples per pixel, pixels per level %s\n",
                   name.c_str(), pt.budget.c_str(), pt.seconds, pt.psnr, pt.psnr_image, pt.samples, traced.c_str());
      c.points.push_back(pt);
    }
    curves.push_back(c);
  };

  uniform_curve("reference", "depth 16, no pruning, uniform n x n (the reference settings)", reference);
  dr::PassOptions roulette = reference;
  roulette.trace.prune_throughput = 0.01f;
  roulette.trace.roulette = true;
  uniform_curve("roulette", "depth 16, Russian roulette below 0.01, uniform n x n", roulette);
  for (const double threshold : parse_list(roulette_text)) {
    dr::PassOptions o = roulette;
    o.trace.prune_throughput = float(threshold);
    char name[32];
    std::snprintf(name, sizeof name, "roulette %g", threshold);
    uniform_curve(name, std::string("depth 16, Russian roulette below ") + (name + 9) + ", uniform n x n", o);
  }
  dr::PassOptions path = roulette;
  path.trace.tree_depth = 2;
  uniform_curve("roulette+path", "as roulette, the Fresnel tree for 2 interactions, one sampled branch beyond", path);
  if (!gpu) {
    for (const double angle : parse_list(footprint_text)) {
      dr::FootprintSettings f;
      f.max_angle = float(angle);
      char name[40];
      std::snprintf(name, sizeof name, "footprints %g", angle);
      uniform_curve(name, std::string("as roulette, the environment averaged over each stratum's footprint (edges up to ") +
                              (name + 11) + " rad)", roulette, &f);
    }
    // one curve per first grids, tolerance, dilation and roulette threshold; a point per last grid
    std::vector<std::pair<std::string, std::vector<LevelSpec>>> groups;
    for (const LevelSpec& spec : level_specs) {
      std::string first;
      for (std::size_t g = 0; g + 1 < spec.grids.size(); ++g) first += std::to_string(spec.grids[g]) + "-";
      char name[96];
      std::snprintf(name, sizeof name, "levels %sm/t%g/d%d/r%g", first.c_str(), double(spec.tolerance), spec.dilate,
                    double(spec.roulette));
      auto it = std::find_if(groups.begin(), groups.end(), [&](const auto& g) { return g.first == name; });
      if (it == groups.end()) {
        groups.push_back({name, {}});
        it = groups.end() - 1;
      }
      it->second.push_back(spec);
    }
    for (const auto& [name, points] : groups) {
      dr::PassOptions o = roulette;
      o.trace.prune_throughput = points.front().roulette;
      levels_curve(name,
                   "roulette below the threshold (r), levels of uniform grids: every pixel on the first, the pixels "
                   "whose samples spread by more than t levels and those within d of them on the next (m: the last)",
                   o, points);
    }
    adaptive_curve("adaptive", "as roulette, adaptive: rounds of 2x2 samples, 2 to 64 of them", roulette);
    adaptive_curve("adaptive+path", "as adaptive, the Fresnel tree for 2 interactions, one sampled branch beyond",
                   path);
  }

  const std::vector<double> targets = parse_list(targets_text);
  nlohmann::json j;
  j["scene"] = {{"mesh", mesh_name},     {"ior", ior},         {"environment", env_name}, {"width", cam.width},
                {"height", cam.height}, {"view", view}, {"threads", threads}, {"device", device}};
  j["quality"] = "PSNR of the 8-bit tone-mapped image over object pixels against uniform " +
                 std::to_string(converged_per_axis) + " x " + std::to_string(converged_per_axis) +
                 ", depth 16, no pruning";
  for (const Curve& c : curves) {
    nlohmann::json jc;
    jc["description"] = c.description;
    for (const Point& pt : c.points)
      jc["points"].push_back({{"budget", pt.budget},
                              {"seconds", pt.seconds},
                              {"psnr", pt.psnr},
                              {"psnr_image", pt.psnr_image},
                              {"samples", pt.samples},
                              {"worst5_error_share", pt.worst.worst_share},
                              {"psnr_without_worst5", pt.worst.psnr_without_worst}});
    j["settings"][c.name] = jc;
  }
  std::printf("\n%-14s", "target dB");
  for (const Curve& c : curves) std::printf(" %20s", c.name.c_str());
  std::printf("\n");
  for (double target : targets) {
    const double base = seconds_at(curves[0], target);
    std::printf("%-14.1f", target);
    nlohmann::json row;
    row["target_psnr"] = target;
    for (const Curve& c : curves) {
      const double sec = seconds_at(c, target);
      char cell[64];
      if (sec < 0) std::snprintf(cell, sizeof cell, "not reached");
      else if (base < 0) std::snprintf(cell, sizeof cell, "%.4f s", sec);
      else std::snprintf(cell, sizeof cell, "%.4f s (%.2fx)", sec, base / sec);
      std::printf(" %20s", cell);
      row[c.name] = {{"seconds", sec < 0 ? nlohmann::json(nullptr) : nlohmann::json(sec)},
                     {"speedup", sec < 0 || base < 0 ? nlohmann::json(nullptr) : nlohmann::json(base / sec)}};
    }
    std::printf("\n");
    j["at_target"].push_back(row);
  }
  std::filesystem::create_directories(out_dir);
  std::ofstream(std::filesystem::path(out_dir) / "equal_quality.json") << j.dump(2) << "\n";
  std::printf("(speed-up: the reference settings' time at the target divided by the setting's; written %s)\n",
              (std::filesystem::path(out_dir) / "equal_quality.json").string().c_str());
  return 0;
}
