// Gradients of a sum of traced rays, three ways, shared by the tracer's tests
// (tests/render/tracer.test.cpp, tests/render/recomputed_trace.test.cpp):
// the whole tape (trace<Var<double>>, one sweep), the streamed reverse mode
// (trace_streamed) and the recomputed one (trace_recomputed); the loss they
// differentiate, in double; the rays and scenes they are tried on.
#pragma once

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "support/ad_check.hpp"
#include "support/shapes.hpp"

#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/passes.hpp"
#include "difftrans/render/recomputed_trace.hpp"

namespace dt_test {

using difftrans::render::HostScene;
using difftrans::render::SceneGradient;
using difftrans::render::TraceSettings;
using difftrans::render::TraceStats;

struct TestRay {
  Vec3f o, d;
};

inline HostScene make_scene(const Shape& shape, float ior) {
  HostScene s(shape.positions, shape.triangles, "test mesh");
  s.ior = ior;
  return s;
}

// A smooth, varied environment for gradient tests.
inline void smooth_environment(HostScene& s, int w = 24, int h = 12) {
  s.set_environment_map(smooth_sky(w, h), w, h);
}

template <class S>
inline Vec3d trace_value(const HostScene& s, const TestRay& r, const TraceSettings& ts, TraceStats* st = nullptr) {
  const ad::ParamSet params = s.params();
  ad::ParamReader<S> reader(&params);
  return to_d(difftrans::render::trace<S>(s.view(false), s.accel(), reader, r.o, r.d, ts, st));
}

// Loss = Σ_rays w · L(ray), in double.
inline double loss(const HostScene& s, const std::vector<TestRay>& rays, const Vec3d& w, const TraceSettings& ts) {
  double sum = 0;
  for (const auto& r : rays) sum += glm::dot(trace_value<double>(s, r, ts), w);
  return sum;
}

// What each reverse-mode gradient below records on: the scene's parameters
// (attached to `gradient` when given), a tape in double, its leaf log and a
// reader of the parameters on them.
struct ReverseRun {
  ad::ParamSet params;
  ad::Tape<double> tape{1 << 20};
  std::vector<ad::LeafRecord> log = std::vector<ad::LeafRecord>(1 << 16);
  ad::ParamReader<ad::Var<double>> reader;
  explicit ReverseRun(const HostScene& s, SceneGradient* gradient = nullptr)
      : params(s.params()), reader(&params, &tape, log.data(), std::int32_t(log.size())) {
    if (gradient) gradient->attach(params);
  }
  ReverseRun(const ReverseRun&) = delete;
  ReverseRun& operator=(const ReverseRun&) = delete;
};

// Reverse-mode gradient of the loss in Var<double>; also reports tape sizes.
inline SceneGradient loss_gradient(const HostScene& s, const std::vector<TestRay>& rays, const Vec3d& w,
                            const TraceSettings& ts, bool* all_finite_out = nullptr) {
  SceneGradient g(s);
  ReverseRun run(s, &g);
  ad::Tape<double>& tape = run.tape;
  ad::ParamReader<ad::Var<double>>& reader = run.reader;
  bool finite = true;
  for (const auto& r : rays) {
    tape.reset();
    reader.clear();
    const Vec3<ad::Var<double>> L = difftrans::render::trace<ad::Var<double>>(s.view(true, true), s.accel(), reader, r.o, r.d, ts);
    REQUIRE_FALSE(tape.overflowed());
    REQUIRE_FALSE(reader.overflowed());
    finite = finite && all_finite(L);
    tape.zero_adjoints();
    for (int c = 0; c < 3; ++c) tape.seed(L[c], w[c]);
    tape.propagate();
    reader.scatter();
  }
  g.fold_normals(s);
  for (auto* v : {&g.positions, &g.ior, &g.absorption, &g.environment})
    for (float x : *v) finite = finite && std::isfinite(x);
  if (all_finite_out) *all_finite_out = finite;
  return g;
}

// The same gradient by the streamed reverse mode (trace_streamed); also the
// largest tape it held and the largest full tape of trace<Var> on the same rays.
// recompute: by trace_recomputed instead (each segment traced again on a
// tape of one segment); `mismatched` counts its segments whose second trace
// made other children than the first.
inline SceneGradient streamed_gradient(const HostScene& s, const std::vector<TestRay>& rays, const Vec3d& w,
                                const TraceSettings& ts, std::vector<Vec3d>* radiance, std::int32_t* peak,
                                bool recompute = false, int* mismatched = nullptr) {
  SceneGradient g(s);
  ReverseRun run(s, &g);
  ad::Tape<double>& tape = run.tape;
  ad::ParamReader<ad::Var<double>>& reader = run.reader;
  *peak = 0;
  for (const auto& r : rays) {
    const Vec3<double> L =
        recompute ? difftrans::render::trace_recomputed<double>(s.view(true, true), s.accel(), reader, r.o, r.d, w,
                                                                ts, nullptr, {}, mismatched)
                  : difftrans::render::trace_streamed<double>(s.view(true, true), s.accel(), reader, r.o, r.d, w, ts);
    REQUIRE_FALSE(tape.overflowed());
    REQUIRE_FALSE(reader.overflowed());
    CHECK(reader.size() == 0);  // every leaf scattered
    radiance->push_back(Vec3d(L));
    *peak = std::max(*peak, tape.peak());
  }
  g.fold_normals(s);
  return g;
}

// trace<Var> on each ray with the whole tape: the tapes' total and largest
// length, and the radiance.
struct WholeTape {
  std::int64_t total = 0;
  std::int32_t peak = 0;
  std::vector<Vec3d> radiance;
};
inline WholeTape whole_tape(const HostScene& s, const std::vector<TestRay>& rays, const TraceSettings& ts) {
  using V = ad::Var<double>;
  ReverseRun run(s);
  ad::Tape<double>& tape = run.tape;
  ad::ParamReader<V>& reader = run.reader;
  WholeTape out;
  for (const auto& r : rays) {
    tape.reset();
    reader.clear();
    const Vec3<V> L = difftrans::render::trace<V>(s.view(true, true), s.accel(), reader, r.o, r.d, ts);
    out.radiance.emplace_back(L.x.value, L.y.value, L.z.value);
    out.total += tape.size();
    out.peak = std::max(out.peak, tape.size());
  }
  return out;
}

// Rays from a camera at `eye` towards jittered points around the origin.
inline std::vector<TestRay> rays_towards_centre(const Vec3f& eye, float spread, int count) {
  std::vector<TestRay> rays;
  for (int i = 0; i < count; ++i) {
    const float a = 2.399963f * float(i), r = spread * std::sqrt((i + 0.5f) / float(count));
    const Vec3f target(r * std::cos(a), r * std::sin(a), 0.05f * float(i % 3));
    rays.push_back({eye, glm::normalize(target - eye)});
  }
  return rays;
}

// The settings the reverse modes are compared under, on a sphere, each with
// its absorption (0 none, 1 homogeneous, 2 a 4³ grid: set_case_absorption).
struct GradientCase {
  const char* name;
  TraceSettings ts;
  int absorption;
};
inline std::vector<GradientCase> gradient_cases() {
  TraceSettings tree;
  tree.max_depth = 10;
  TraceSettings drawn = tree;  // one path beyond 3 interactions, roulette below 0.05
  drawn.max_depth = 16;
  drawn.tree_depth = 3;
  drawn.roulette = true;
  drawn.prune_throughput = 0.05f;
  TraceSettings main_path = tree;
  main_path.gradient_refractions = 2;
  TraceSettings cut = tree;  // constants below the third interaction
  cut.gradient_depth = 3;
  TraceSettings sampled = drawn;  // stage 2's training: the grid integrated by 4 samples per segment
  sampled.integration.samples = 4;
  sampled.integration.offset = 0.3f;
  TraceSettings held = sampled;  // the absorption's derivative without the segments' ends (stage 2's vertex phase)
  held.attenuation_path_gradient = false;
  return {{"full tree, clear", tree, 0},
          {"full tree, homogeneous", tree, 1},
          {"full tree, grid", tree, 2},
          {"drawn path and roulette", drawn, 2},
          {"main refraction path", main_path, 1},
          {"gradient depth 3", cut, 2},
          {"drawn path, grid by 4 samples", sampled, 2},
          {"drawn path, grid by 4 samples, its ends held", held, 2}};
}
inline void set_case_absorption(HostScene& s, int absorption) {
  if (absorption == 0) {
    s.absorption_kind = difftrans::scene::AbsorptionKind::none;
    s.absorption_raw.clear();
  }
  if (absorption == 1) s.set_homogeneous_absorption(Vec3f(0.5f, 1.0f, 2.0f));
  if (absorption == 2) {
    std::vector<float> raw;
    for (int i = 0; i < 4 * 4 * 4; ++i)
      for (int k = 0; k < 3; ++k) raw.push_back(difftrans::scene::raw_from_sigma(0.3f + 0.1f * float((i * 7 + k) % 5)));
    s.set_grid_absorption(difftrans::Vec3i(4), Vec3f(-0.6f), Vec3f(0.6f), std::move(raw));
  }
}

// Checks that b equals a within 1e-5 of a's largest entry (float rounding of
// the sums); returns that largest entry.
inline float same_gradient(const std::vector<float>& a, const std::vector<float>& b, const char* what) {
  CAPTURE(what);
  REQUIRE(a.size() == b.size());
  float scale = 0.0f, worst = 0.0f;
  for (std::size_t i = 0; i < a.size(); ++i) {
    scale = std::max(scale, std::abs(a[i]));
    worst = std::max(worst, std::abs(a[i] - b[i]));
  }
  CHECK(worst <= 1e-5f * std::max(scale, 1e-12f));
  return scale;
}

// spot (data/meshes, normalized) at IoR 1.472 under the smooth sky, 16 rays
// through it traced to depth 16 (a bushy Fresnel tree), and the whole
// tape's gradient of the loss with weights w on them.
struct SpotDeepTree {
  HostScene scene;
  std::vector<TestRay> rays;
  TraceSettings settings;
  SceneGradient full;
  explicit SpotDeepTree(const Vec3d& w)
      : scene(spot_under_sky()),
        rays(rays_towards_centre(Vec3f(0.4f, 0.5f, 3.0f), 0.3f, 16)),
        settings(depth_16()),
        full(loss_gradient(scene, rays, w, settings)) {}
  static HostScene spot_under_sky() {
    HostScene spot = make_scene(load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/spot.obj"), 1.472f);
    smooth_environment(spot);
    return spot;
  }
  static TraceSettings depth_16() {
    TraceSettings ts;
    ts.max_depth = 16;
    return ts;
  }
};

}  // namespace dt_test
