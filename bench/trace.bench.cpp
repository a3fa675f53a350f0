// The tracer against its limit. On spot, bunny and horse (data/,
// normalized), the camera rays of a 256² protocol view that hit the object
// are traced single-threaded at depth 4 and 8:
//   embree    the host accelerator alone on exactly the segments the tracer
//             intersects: Embree (named bvh in a build without Embree, where
//             HostScene traces with the portable BVH)
//   primal    trace<float>
//   primal_arrays  trace<float> with the hit triangle read from the mesh's
//             arrays (indices, positions, normals) instead of its record
//             (scene::TriangleRecord): the same radiance, bit for bit
//   gradient  trace<Var<float>> + backward + scatter (one tape per ray)
//   dual_ior  trace<Dual<float, 1>>, derivative along the IoR
// Each iteration processes every camera ray once (items = camera rays), so
// the printed ratios are time per camera ray relative to the accelerator alone.
// Targets: primal at depth 4 within 2x Embree; gradient within 4x primal.
// horse/absorption/*: primal, gradient and recomputed gradient at stage 2's
// training settings for each absorption model (none, homogeneous, grids of 4³
// and 16³), as ratios to the clear primal; for the grids also primal_untabled
// and recomputed_untabled, σ evaluated at each read instead of read from the
// scene's softplus table (what the table saves). */d16/*: depth 16 through clear
// glass, the tape of a camera ray (mean and largest) with the whole tape,
// streamed (render::trace_streamed) and recomputed (render::trace_recomputed:
// half a segment's tape at a time), for the whole tree, roulette below 0.01
// and stage 2's training settings.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "difftrans/io/mesh_file.hpp"
#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/recomputed_trace.hpp"
#include "difftrans/scene/camera.hpp"
#include "support/ratio_reporter.hpp"

namespace dr = difftrans::render;
namespace ad = difftrans::ad;
using difftrans::Vec3f;

namespace {

// Wraps an intersector and logs every ray it is asked about.
struct RecordingAccel {
  const dr::HostAccel* inner;
  std::vector<std::pair<Vec3f, Vec3f>>* log;
  difftrans::accel::RayHit intersect(const Vec3f& o, const Vec3f& d, float tnear, float tfar) const {
    log->emplace_back(o, d);
    return inner->intersect(o, d, tnear, tfar);
  }
};

struct Workload {
  std::unique_ptr<dr::HostScene> scene;
  std::vector<difftrans::scene::Ray> rays;                       // camera rays that hit the object
  std::vector<std::pair<Vec3f, Vec3f>> segments[2];              // depth 4, depth 8
};

Workload& workload(const std::string& name) {
  static std::map<std::string, Workload> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return it->second;
  Workload& w = cache[name];
  difftrans::io::Mesh m = difftrans::io::read_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/" + name + ".obj");
  difftrans::io::normalize_to_unit_box(m);
  std::vector<float> p;
  std::vector<std::int32_t> t;
  for (const auto& v : m.positions) p.insert(p.end(), {v.x, v.y, v.z});
  for (const auto& f : m.triangles) t.insert(t.end(), {f.x, f.y, f.z});
  w.scene = std::make_unique<dr::HostScene>(std::move(p), std::move(t), name);
  w.scene->ior = 1.5f;
  std::vector<float> env;  // a smooth 512 x 256 sky, so look-ups cost what a real map costs
  for (int r = 0; r < 256; ++r)
    for (int c = 0; c < 512; ++c)
      env.insert(env.end(), {0.5f + 0.5f * std::sin(c * 0.0123f), 0.5f + 0.4f * std::cos(r * 0.021f), 0.7f});
  w.scene->set_environment_map(std::move(env), 512, 256);
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.3f, 0.5f, 1.0f), 256, 256);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const auto r = cam.generate_ray(x, y);
      if (w.scene->accel().intersect(r.origin, r.direction).hit()) w.rays.push_back(r);
    }
  const dr::SceneView view = w.scene->view(false);
  const ad::ParamSet params = w.scene->params();
  ad::ParamReader<float> reader(&params);
  for (int k = 0; k < 2; ++k) {
    dr::TraceSettings ts;
    ts.max_depth = k == 0 ? 4 : 8;
    RecordingAccel rec{&w.scene->accel(), &w.segments[k]};
    for (const auto& r : w.rays) dr::trace<float>(view, rec, reader, r.origin, r.direction, ts);
  }
  std::fprintf(stderr, "%s: %d triangles, %zu camera rays through the object, %.2f / %.2f segments per ray (depth 4 / 8)\n",
               name.c_str(), w.scene->mesh.num_triangles(), w.rays.size(),
               double(w.segments[0].size()) / double(w.rays.size()), double(w.segments[1].size()) / double(w.rays.size()));
  return w;
}

dr::TraceSettings settings(int depth) {
  dr::TraceSettings ts;
  ts.max_depth = depth;
  return ts;
}

// The settings stage 2 trains with (examples/pipeline/materials.hpp): the
// Fresnel tree to 8 interactions, one drawn path to 16, pruning at 0.01 by
// Russian roulette, 4 samples of a grid's absorption integral per segment.
dr::TraceSettings training_settings() {
  dr::TraceSettings ts;
  ts.max_depth = 16;
  ts.tree_depth = 8;
  ts.roulette = true;
  ts.prune_throughput = 0.01f;
  ts.integration.samples = 4;
  return ts;
}

// The absorption models stage 2 chooses from, all with σ = 0.05 per unit
// length everywhere: light enough that every model traces the same branches
// as clear glass (pruning follows the throughput), so the ratios are the
// cost of the integration alone.
// Each benchmark sets its own (the workload's scene is shared).
enum class Absorption { none, homogeneous, grid4, grid16 };
void set_absorption(dr::HostScene& s, Absorption a) {
  if (a == Absorption::none) {
    s.absorption_kind = difftrans::scene::AbsorptionKind::none;
    s.absorption_raw.clear();
  } else if (a == Absorption::homogeneous) {
    s.set_homogeneous_absorption(Vec3f(0.05f));
  } else {
    const int n = a == Absorption::grid4 ? 4 : 16;
    std::vector<float> raw(std::size_t(n) * std::size_t(n) * std::size_t(n) * 3, difftrans::scene::raw_from_sigma(0.05f));
    s.set_grid_absorption(difftrans::Vec3i(n), Vec3f(-0.55f), Vec3f(0.55f), std::move(raw));
  }
}

void accel_alone(benchmark::State& state, std::string name, int depth) {
  Workload& w = workload(name);
  const auto& segs = w.segments[depth == 4 ? 0 : 1];
  for (auto _ : state)
    for (const auto& [o, d] : segs) benchmark::DoNotOptimize(w.scene->accel().intersect(o, d));
  state.SetItemsProcessed(state.iterations() * std::int64_t(w.rays.size()));
  state.counters["segments_per_second"] = benchmark::Counter(double(segs.size()) * double(state.iterations()), benchmark::Counter::kIsRate);
}

// records false: the hits read the mesh's arrays, not its triangle records;
// softplus_table false: σ = softplus(raw) evaluated at every grid corner a
// sample reads, not read from the scene's table (AbsorptionField::softplus_table).
void primal(benchmark::State& state, std::string name, dr::TraceSettings ts, Absorption absorption,
            bool records, bool softplus_table) {
  Workload& w = workload(name);
  set_absorption(*w.scene, absorption);
  dr::SceneView view = w.scene->view(false);
  if (!records) view.mesh.records = nullptr;
  if (!softplus_table) view.absorption.softplus_table = nullptr;
  const ad::ParamSet params = w.scene->params();
  ad::ParamReader<float> reader(&params);
  for (auto _ : state)
    for (const auto& r : w.rays)
      benchmark::DoNotOptimize(dr::trace<float>(view, w.scene->accel(), reader, r.origin, r.direction, ts));
  state.SetItemsProcessed(state.iterations() * std::int64_t(w.rays.size()));
}

// How the gradient pass keeps its tape. streamed: trace_streamed, the
// gradient swept back branch by branch as the tree is traced; recomputed:
// trace_recomputed, each segment traced again on a tape of its own when its
// subtrees are done (tape_bytes_* count each ray's peak for both); whole:
// trace<Var> with the whole tape, then one sweep.
enum class TapeMode { whole, streamed, recomputed };

void gradient(benchmark::State& state, std::string name, dr::TraceSettings ts, Absorption absorption,
              TapeMode mode, bool softplus_table) {
  using V = ad::Var<float>;
  Workload& w = workload(name);
  set_absorption(*w.scene, absorption);
  dr::SceneView view = w.scene->view(true, true);
  if (!softplus_table) view.absorption.softplus_table = nullptr;
  ad::ParamSet params = w.scene->params();
  dr::SceneGradient grad(*w.scene);
  grad.attach(params);
  ad::Tape<float> tape(1 << 22);
  std::vector<ad::LeafRecord> log(1 << 18);
  ad::ParamReader<V> reader(&params, &tape, log.data(), std::int32_t(log.size()));
  double nodes = 0, rays = 0, overflow = 0, most = 0;
  const difftrans::Vec3<float> adjoint(1.0f);
  for (auto _ : state)
    for (const auto& r : w.rays) {
      if (mode != TapeMode::whole) {
        benchmark::DoNotOptimize(
            mode == TapeMode::streamed
                ? dr::trace_streamed<float>(view, w.scene->accel(), reader, r.origin, r.direction, adjoint, ts)
                : dr::trace_recomputed<float>(view, w.scene->accel(), reader, r.origin, r.direction, adjoint, ts));
        nodes += tape.peak();
        most = std::max(most, double(tape.peak()));
        rays += 1;
        if (tape.overflowed() || reader.overflowed()) ++overflow;
        continue;
      }
      tape.reset();
      reader.clear();
      const difftrans::Vec3<V> L = dr::trace<V>(view, w.scene->accel(), reader, r.origin, r.direction, ts);
      nodes += tape.size();
      most = std::max(most, double(tape.size()));
      rays += 1;
      if (tape.overflowed() || reader.overflowed()) {
        ++overflow;
        continue;
      }
      tape.zero_adjoints();
      for (int c = 0; c < 3; ++c) tape.seed(L[c], 1.0f);
      tape.propagate();
      reader.scatter();
    }
  grad.fold_normals(*w.scene);  // once per sweep, as render_gradient does
  state.SetItemsProcessed(state.iterations() * std::int64_t(w.rays.size()));
  state.counters["tape_bytes_per_ray"] = nodes / rays * double(ad::Tape<float>::bytes_per_node);
  state.counters["tape_bytes_max"] = most * double(ad::Tape<float>::bytes_per_node);
  state.counters["overflowed_rays"] = overflow;
}

void dual_ior(benchmark::State& state, std::string name, int depth) {
  using D = ad::Dual<float, 1>;
  Workload& w = workload(name);
  set_absorption(*w.scene, Absorption::none);
  // only the IoR carries a tangent: every other unknown is read as a constant
  for (int b = 0; b < dr::param_count; ++b) w.scene->differentiate[b] = b == dr::param_ior;
  const dr::SceneView view = w.scene->view(true);
  for (bool& d : w.scene->differentiate) d = true;
  ad::ParamSet params = w.scene->params();
  const float one = 1.0f;
  params.buffers[dr::param_ior].tangents[0] = &one;
  ad::ParamReader<D> reader(&params);
  const dr::TraceSettings ts = settings(depth);
  for (auto _ : state)
    for (const auto& r : w.rays)
      benchmark::DoNotOptimize(dr::trace<D>(view, w.scene->accel(), reader, r.origin, r.direction, ts));
  state.SetItemsProcessed(state.iterations() * std::int64_t(w.rays.size()));
}

}  // namespace

int main(int argc, char** argv) {
#if DIFFTRANS_HAVE_EMBREE
  const std::string baseline = "embree";
#else
  const std::string baseline = "bvh";
#endif
  std::vector<std::pair<std::string, std::string>> groups;
  for (const std::string name : {"spot", "bunny", "horse"})
    for (int depth : {4, 8}) {
      const std::string prefix = name + "/d" + std::to_string(depth) + "/";
      benchmark::RegisterBenchmark((prefix + baseline).c_str(), accel_alone, name, depth)->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark((prefix + "primal").c_str(), primal, name, settings(depth), Absorption::none, true, true)
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark((prefix + "primal_arrays").c_str(), primal, name, settings(depth),
                                   Absorption::none, false, true)
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark((prefix + "gradient").c_str(), gradient, name, settings(depth),
                                   Absorption::none, TapeMode::whole, true)
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark((prefix + "dual_ior").c_str(), dual_ior, name, depth)->Unit(benchmark::kMillisecond);
      groups.emplace_back(prefix, prefix + baseline);
    }
  // What each absorption model costs the tracer at stage 2's training
  // settings, relative to clear glass (horse/absorption/none/primal): the
  // tracer skips the integration when there is none and uses the closed form
  // for a homogeneous σ.
  const std::pair<const char*, Absorption> models[] = {{"none", Absorption::none},
                                                       {"homogeneous", Absorption::homogeneous},
                                                       {"grid4", Absorption::grid4},
                                                       {"grid16", Absorption::grid16}};
  for (const auto& [label, model] : models) {
    const std::string prefix = std::string("horse/absorption/") + label + "/";
    benchmark::RegisterBenchmark((prefix + "primal").c_str(), primal, "horse", training_settings(), model, true, true)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark((prefix + "gradient").c_str(), gradient, "horse", training_settings(), model, TapeMode::whole,
                                 true)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark((prefix + "recomputed").c_str(), gradient, "horse", training_settings(), model,
                                 TapeMode::recomputed, true)
        ->Unit(benchmark::kMillisecond);
    if (model == Absorption::grid4 || model == Absorption::grid16) {  // what the softplus table saves a grid
      benchmark::RegisterBenchmark((prefix + "primal_untabled").c_str(), primal, "horse", training_settings(), model,
                                   true, false)
          ->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark((prefix + "recomputed_untabled").c_str(), gradient, "horse", training_settings(),
                                   model, TapeMode::recomputed, false)
          ->Unit(benchmark::kMillisecond);
    }
  }
  groups.emplace_back("horse/absorption/", "horse/absorption/none/primal");
  // The tape of one camera ray at depth 16 (counters tape_bytes_per_ray and
  // tape_bytes_max) through clear glass: the whole Fresnel tree, Russian
  // roulette below 0.01, and stage 2's training settings; times relative to
  // the whole tree's primal.
  for (const std::string name : {"spot", "bunny", "horse"}) {
    const std::string prefix = name + "/d16/";
    dr::TraceSettings roulette = settings(16);
    roulette.roulette = true;
    roulette.prune_throughput = 0.01f;
    benchmark::RegisterBenchmark((prefix + "primal").c_str(), primal, name, settings(16), Absorption::none, true, true)
        ->Unit(benchmark::kMillisecond);
    const std::pair<const char*, dr::TraceSettings> variants[] = {
        {"", settings(16)}, {"_roulette", roulette}, {"_training", training_settings()}};
    const std::pair<const char*, TapeMode> modes[] = {
        {"gradient", TapeMode::whole}, {"streamed", TapeMode::streamed}, {"recomputed", TapeMode::recomputed}};
    for (const auto& [label, mode] : modes)
      for (const auto& [suffix, ts] : variants)
        benchmark::RegisterBenchmark((prefix + label + suffix).c_str(), gradient, name, ts, Absorption::none, mode, true)
            ->Unit(benchmark::kMillisecond);
    groups.emplace_back(prefix, prefix + "primal");
  }
  return dt_bench::run_with_ratios(argc, argv, groups);
}
