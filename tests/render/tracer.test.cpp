// The recursive tracer against analytic oracles — a parallel plate at normal
// and oblique incidence (closed-form series of internal reflections), a glass
// sphere's central ray, the white furnace — its gradients against central
// finite differences in double (vertices, IoR, homogeneous and grid
// absorption, environment texels; sphere, cube, spot), forward against
// reverse mode (the hard cases are in hard_cases.test.cpp), the streamed
// reverse mode against the whole tape (the recomputed one:
// recomputed_trace.test.cpp; the helpers of both: support/trace_gradients.hpp).
// Near-field escapes: rays that leave the object read a radiance field (or a
// room) at their own origin and direction. The triangle records give the
// radiance and IoR derivative of the mesh arrays.
#include "support/ad_check.hpp"
#include "support/shapes.hpp"
#include "support/trace_gradients.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/passes.hpp"
#include "difftrans/scene/room.hpp"

using namespace dt_test;
using difftrans::render::HostScene;
using difftrans::render::SceneGradient;
using difftrans::render::TraceSettings;
using difftrans::render::TraceStats;

namespace {

// An environment that is A towards −Z (the map's centre columns) and B
// towards +Z (the seam columns): 8 × 2 texels, so the lookup is exactly A
// for u in [0.3125, 0.6875] and exactly B within 0.1875 of the seam.
void two_sided_environment(HostScene& s, const Vec3f& A, const Vec3f& B) {
  std::vector<float> t;
  for (int row = 0; row < 2; ++row)
    for (int col = 0; col < 8; ++col) {
      const Vec3f c = col >= 2 && col <= 5 ? A : B;
      t.insert(t.end(), {c.x, c.y, c.z});
    }
  s.set_environment_map(t, 8, 2);
}

// The entries of `grad` with the largest magnitude.
std::vector<std::size_t> largest(const std::vector<float>& grad, std::size_t count) {
  std::vector<std::size_t> idx(grad.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) { return std::abs(grad[a]) > std::abs(grad[b]); });
  idx.resize(std::min(count, idx.size()));
  return idx;
}

// Central difference of the loss w.r.t. one float parameter.
template <class Apply>
double loss_difference(HostScene& s, const std::vector<TestRay>& rays, const Vec3d& w, const TraceSettings& ts,
                       float& param, double h, Apply&& changed) {
  const float keep = param;
  param = float(double(keep) + h);
  const double hp = double(param) - double(keep);
  changed();
  const double up = loss(s, rays, w, ts);
  param = float(double(keep) - h);
  const double hm = double(keep) - double(param);
  changed();
  const double down = loss(s, rays, w, ts);
  param = keep;
  changed();
  return (up - down) / (hp + hm);
}

void check_against_differences(HostScene& s, const std::vector<TestRay>& rays, const TraceSettings& ts,
                               const std::string what) {
  CAPTURE(what);
  const Vec3d w(0.7, 1.0, 1.3);
  const SceneGradient g = loss_gradient(s, rays, w, ts);
  const auto nothing = [] {};
  int checked = 0, kinks = 0;
  const auto check = [&](const std::string name, float reverse, float& param, double h, auto&& changed) {
    CAPTURE(name);
    // two step sizes: where they disagree the loss is not smooth at this
    // parameter (a path changes triangle or crosses the TIR boundary within
    // the step), and no finite difference is an oracle there
    const double fd_h = loss_difference(s, rays, w, ts, param, h, changed);
    const double fd_h2 = loss_difference(s, rays, w, ts, param, h / 2, changed);
    const double scale = std::max(1.0, std::abs(fd_h2));
    if (std::abs(fd_h - fd_h2) > 0.05 * scale) {
      ++kinks;
      MESSAGE(what << ": " << name << " not smooth within the step (" << fd_h << " vs " << fd_h2 << "), skipped");
      return;
    }
    const double fd = (4 * fd_h2 - fd_h) / 3;  // Richardson: O(h⁴)
    CAPTURE(reverse);
    CAPTURE(fd);
    CHECK(std::abs(reverse - fd) <= 2e-3 * scale);
    ++checked;
  };
  check("ior", g.ior[0], s.ior, 1e-3, nothing);
  for (std::size_t i : largest(g.positions, 8))
    // steps well below spot's edge length: at 1e-3 a path may change triangle within the step
    // (measured: spot's coordinate 7174 gives FD -133 at h = 1e-3, -6.6203 at 1e-4, reverse -6.6245)
    check("vertex coordinate", g.positions[i], s.mesh.positions[i], 1e-4, [&] { s.positions_changed(); });
  for (std::size_t i : largest(g.environment, 4)) check("texel", g.environment[i], s.environment[i], 1e-2, nothing);
  for (std::size_t i : largest(g.absorption, 6)) check("absorption", g.absorption[i], s.absorption_raw[i], 1e-3, nothing);
  CHECK(checked >= 11);
  CHECK(kinks <= checked / 4);
}

// Slab transfer at one interface pair: single-interface R, internal
// transmittance a = exp(−σ path); the closed-form sums of all internal
// reflections (Born & Wolf), up to `depth` interactions in the tracer's counting.
struct SlabSeries {
  double reflected = 0, transmitted = 0;
};
SlabSeries slab_series(double R, double a, int depth) {
  SlabSeries s;
  s.reflected = R;  // first interaction: reflection off the front face
  // transmitted after k internal round trips uses 2 + 2k interactions
  for (int k = 0; 2 + 2 * k <= depth; ++k) s.transmitted += (1 - R) * (1 - R) * std::pow(R * R * a * a, k) * a;
  // reflected back out after k + 1 internal reflections uses 3 + 2k interactions
  for (int k = 0; 3 + 2 * k <= depth; ++k) s.reflected += (1 - R) * (1 - R) * R * a * a * std::pow(R * R * a * a, k);
  return s;
}

}  // namespace

TEST_CASE("the test meshes are closed and outward facing") {
  for (const Shape& sh : {make_box(0.5f, 0.3f, 0.2f), make_icosphere(0.5f, 2)}) {
    double volume = 0;  // divergence theorem: positive for outward triangles
    for (std::size_t f = 0; f < sh.triangles.size(); f += 3) {
      Vec3d p[3];
      for (int k = 0; k < 3; ++k)
        p[k] = Vec3d(sh.positions[3 * sh.triangles[f + k]], sh.positions[3 * sh.triangles[f + k] + 1],
                     sh.positions[3 * sh.triangles[f + k] + 2]);
      volume += glm::dot(p[0], glm::cross(p[1], p[2])) / 6.0;
    }
    CHECK(volume > 0);
  }
}

TEST_CASE("parallel plate: closed-form series at normal and oblique incidence") {
  const double eta = 1.5, thickness = 0.2;
  HostScene s = make_scene(make_box(5.0f, 5.0f, float(thickness / 2)), float(eta));
  const Vec3f A(1.0f, 0.5f, 0.25f), B(0.1f, 0.2f, 0.4f);
  two_sided_environment(s, A, B);
  for (double sigma : {0.0, 2.0}) {
    if (sigma > 0) s.set_homogeneous_absorption(Vec3f(float(sigma)));
    for (double theta_deg : {0.0, 30.0, 55.0}) {
      for (int depth : {2, 3, 8, 16}) {
        CAPTURE(sigma);
        CAPTURE(theta_deg);
        CAPTURE(depth);
        const double th = theta_deg * pi_v<double> / 180;
        const TestRay r{Vec3f(float(-2 * std::sin(th)), 0.0f, float(2 * std::cos(th))),
                        Vec3f(float(std::sin(th)), 0.0f, float(-std::cos(th)))};
        TraceSettings ts;
        ts.max_depth = depth;
        ts.smooth_normals = false;  // a box's vertex normals would round its faces
        const Vec3d L = trace_value<double>(s, r, ts);
        const auto f = difftrans::optics::fresnel_dielectric(std::cos(th), eta);
        const double cos_t = -f.cos_theta_t;
        const double a = std::exp(-sigma * thickness / cos_t);
        const SlabSeries series = slab_series(f.R, a, depth);
        const Vec3d expected = series.transmitted * Vec3d(A) + series.reflected * Vec3d(B);
        CAPTURE(L);
        CAPTURE(expected);
        CHECK(glm::length(L - expected) < 1e-5 * glm::length(expected));
      }
    }
  }
}

TEST_CASE("a glass sphere's central ray") {
  const double eta = 1.45, radius = 0.5;
  HostScene s = make_scene(make_icosphere(float(radius), 4), float(eta));
  const Vec3f A(1.0f, 0.8f, 0.6f), B(0.2f, 0.3f, 0.9f);
  two_sided_environment(s, A, B);
  s.set_homogeneous_absorption(Vec3f(0.5f, 1.0f, 3.0f));
  TraceSettings ts;
  ts.max_depth = 16;
  const Vec3d L = trace_value<double>(s, {Vec3f(0, 0, 3), Vec3f(0, 0, -1)}, ts);
  const double R = std::pow((eta - 1) / (eta + 1), 2);
  const double sig[3] = {0.5, 1.0, 3.0};
  for (int c = 0; c < 3; ++c) {
    const SlabSeries series = slab_series(R, std::exp(-sig[c] * 2 * radius), 16);
    // the icosphere's diameter along z is exact at a vertex; elsewhere within the tessellation
    CHECK(L[c] == doctest::Approx(series.transmitted * A[c] + series.reflected * B[c]).epsilon(2e-3));
  }
}

TEST_CASE("TraceStats::min_cos2_t: the refraction closest to the critical angle") {
  // an off-axis ray through a glass sphere, impact parameter b (sin θi = b / r):
  // entering, cos²θt = 1 − (b / r η)²; leaving, 1 − (b / r)², the smaller
  const double eta = 1.5, radius = 0.5, b = 0.3;
  HostScene s = make_scene(make_icosphere(float(radius), 5), float(eta));
  two_sided_environment(s, Vec3f(1.0f), Vec3f(0.5f));
  TraceSettings ts;
  const TestRay ray{Vec3f(float(b), 0.0f, 3.0f), Vec3f(0, 0, -1)};
  const double s2 = (b / radius) * (b / radius);
  ts.max_depth = 1;  // the entry only
  TraceStats entry;
  trace_value<double>(s, ray, ts, &entry);
  CHECK(entry.min_cos2_t == doctest::Approx(1.0 - s2 / (eta * eta)).epsilon(5e-3));
  ts.max_depth = 2;  // and the exit
  TraceStats both;
  trace_value<double>(s, ray, ts, &both);
  CHECK(both.min_cos2_t == doctest::Approx(1.0 - s2).epsilon(5e-3));
  // a miss refracts nowhere; add() keeps the least of two rays
  TraceStats miss;
  trace_value<double>(s, {Vec3f(2.0f, 0.0f, 3.0f), Vec3f(0, 0, -1)}, ts, &miss);
  CHECK(miss.min_cos2_t == 1.0f);
  miss.add(both);
  CHECK(miss.min_cos2_t == both.min_cos2_t);
}

TEST_CASE("white furnace: clear glass renders the environment, absorbing glass less") {
  for (const Shape& shape : {make_icosphere(0.5f, 3), make_box(0.3f, 0.4f, 0.25f)}) {
    HostScene s = make_scene(shape, 1.5f);
    const double c = double(0.8f);
    s.set_constant_environment(Vec3f(0.8f));
    TraceSettings ts;
    ts.max_depth = 16;
    int through_object = 0;
    for (const TestRay& r : rays_towards_centre(Vec3f(0.4f, 0.9f, 3.0f), 0.6f, 200)) {
      TraceStats st;
      const Vec3d L = trace_value<double>(s, r, ts, &st);
      through_object += st.hits > 0;
      for (int k = 0; k < 3; ++k) {
        CHECK(L[k] <= c * (1 + 1e-9));
        CHECK(L[k] >= c * (1 - st.cut_weight) - 1e-9);  // what is missing is what the depth limit cut
      }
    }
    CHECK(through_object > 100);
    s.set_homogeneous_absorption(Vec3f(1.0f, 2.0f, 3.0f));
    for (const TestRay& r : rays_towards_centre(Vec3f(0.4f, 0.9f, 3.0f), 0.2f, 50)) {
      const Vec3d L = trace_value<double>(s, r, ts);
      CHECK(L.x < c);
      CHECK(L.z < L.x);  // more absorption, darker
    }
  }
}

TEST_CASE("gradients match central finite differences in double") {
  TraceSettings ts;
  ts.max_depth = 5;
  SUBCASE("sphere, homogeneous absorption") {
    HostScene s = make_scene(make_icosphere(0.5f, 3), 1.5f);
    smooth_environment(s);
    s.set_homogeneous_absorption(Vec3f(0.5f, 1.5f, 3.0f));
    check_against_differences(s, rays_towards_centre(Vec3f(0.3f, 0.5f, 3.0f), 0.35f, 6), ts, "sphere");
  }
  SUBCASE("cube, grid absorption") {
    Shape box = make_box(0.35f, 0.3f, 0.25f);
    for (std::size_t i = 0; i < box.positions.size(); i += 3) {  // turn it so no face is axis-aligned
      const float x = box.positions[i], z = box.positions[i + 2];
      box.positions[i] = 0.8f * x + 0.6f * z;
      box.positions[i + 2] = -0.6f * x + 0.8f * z;
    }
    HostScene s = make_scene(box, 1.6f);
    smooth_environment(s);
    std::vector<float> raw;
    for (int i = 0; i < 4 * 4 * 4 * 3; ++i) raw.push_back(difftrans::scene::raw_from_sigma(0.5f + float(i % 7) * 0.3f));
    s.set_grid_absorption(Vec3i(4), Vec3f(-0.6f), Vec3f(0.6f), raw);
    check_against_differences(s, rays_towards_centre(Vec3f(0.2f, 0.6f, 3.0f), 0.2f, 5), ts, "cube");
  }
  SUBCASE("spot") {
    const Shape spot = load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/spot.obj");
    HostScene s = make_scene(spot, 1.472f);
    smooth_environment(s);
    s.set_homogeneous_absorption(Vec3f(0.3f, 0.6f, 1.2f));
    ts.max_depth = 3;
    check_against_differences(s, rays_towards_centre(Vec3f(0.0f, 0.2f, 3.0f), 0.15f, 4), ts, "spot");
  }
}

TEST_CASE("beyond the tree one path drawn by Fresnel weight, pruning by roulette: the full tree on average") {
  HostScene s = make_scene(make_icosphere(0.5f, 3), 1.5f);
  smooth_environment(s);
  s.set_homogeneous_absorption(Vec3f(0.2f, 0.5f, 1.0f));
  TraceSettings full;
  full.max_depth = 16;
  TraceSettings cut = full;  // the tree stopped at 2 interactions
  cut.max_depth = 2;
  TraceSettings drawn = full;  // the tree for 2 interactions, then one path to 16, roulette below 0.05
  drawn.tree_depth = 2;
  drawn.roulette = true;
  drawn.prune_throughput = 0.05f;
  const std::vector<TestRay> rays = rays_towards_centre(Vec3f(0.3f, 0.4f, 3.0f), 0.45f, 4000);
  Vec3d sum_full(0.0), sum_cut(0.0), sum_drawn(0.0);
  std::int64_t segments_full = 0, segments_drawn = 0;
  for (const TestRay& r : rays) {
    TraceStats a, b;
    sum_full += trace_value<double>(s, r, full, &a);
    sum_cut += trace_value<double>(s, r, cut);
    sum_drawn += trace_value<double>(s, r, drawn, &b);
    segments_full += a.segments;
    segments_drawn += b.segments;
  }
  MESSAGE("mean radiance: full tree " << sum_full.x / 4000 << ", " << sum_full.y / 4000 << ", " << sum_full.z / 4000
                                      << "; cut at 2 " << sum_cut.x / 4000 << "; drawn " << sum_drawn.x / 4000 << ", "
                                      << sum_drawn.y / 4000 << ", " << sum_drawn.z / 4000 << "; segments per ray "
                                      << double(segments_full) / 4000 << " -> " << double(segments_drawn) / 4000);
  for (int c = 0; c < 3; ++c) {  // the drawn paths find at least three quarters of the light the cut loses
    CHECK(sum_cut[c] < sum_full[c]);
    CHECK(std::abs(sum_drawn[c] - sum_full[c]) < 0.25 * (sum_full[c] - sum_cut[c]));
  }
  CHECK(segments_drawn < segments_full);
  // the choices hang on the camera ray and the branch's place in the tree:
  // the same ray repeats bit for bit
  for (std::size_t i = 0; i < 50; ++i) {
    const Vec3d a = trace_value<double>(s, rays[i], drawn), b = trace_value<double>(s, rays[i], drawn);
    CHECK(a == b);
  }
  // The gradient: each drawn branch's weight is divided by its probability
  // held constant, so the derivative is that of the full tree on average
  // (not that of one drawn estimate, whose weight ratio is flat in the
  // parameters: a finite difference of it would not be). The IoR and the red
  // absorption over the rays, drawn against the full tree, both in reverse mode.
  // Over 8 groups of 500 rays: the drawn gradient's mean within three
  // standard errors of the full tree's (the drawn branches carry 1/R and
  // 1/T, a heavy tail where R is small).
  const Vec3d w(1.0, 1.0, 1.0);
  double diff_ior = 0.0, diff_ior2 = 0.0, diff_abs = 0.0, diff_abs2 = 0.0, full_ior = 0.0, full_abs = 0.0;
  for (int group = 0; group < 8; ++group) {
    const std::vector<TestRay> part(rays.begin() + 500 * group, rays.begin() + 500 * (group + 1));
    const SceneGradient g_full = loss_gradient(s, part, w, full), g_drawn = loss_gradient(s, part, w, drawn);
    const double di = double(g_drawn.ior[0]) - double(g_full.ior[0]);
    const double da = double(g_drawn.absorption[0]) - double(g_full.absorption[0]);
    diff_ior += di / 8;
    diff_ior2 += di * di / 8;
    diff_abs += da / 8;
    diff_abs2 += da * da / 8;
    full_ior += double(g_full.ior[0]);
    full_abs += double(g_full.absorption[0]);
  }
  const double se_ior = std::sqrt(std::max(0.0, diff_ior2 - diff_ior * diff_ior) / 7.0);
  const double se_abs = std::sqrt(std::max(0.0, diff_abs2 - diff_abs * diff_abs) / 7.0);
  MESSAGE("per 500 rays: dL/dIoR full " << full_ior / 8 << ", drawn - full " << diff_ior << " ± " << se_ior
                                        << "; dL/draw sigma_r full " << full_abs / 8 << ", drawn - full " << diff_abs
                                        << " ± " << se_abs);
  CHECK(std::abs(diff_ior) < 3.0 * se_ior + 0.01 * std::abs(full_ior / 8));
  CHECK(std::abs(diff_abs) < 3.0 * se_abs + 0.01 * std::abs(full_abs / 8));
  CHECK(se_ior < 0.25 * std::abs(full_ior / 8));  // and the check has power
  const std::vector<TestRay> few(rays.begin(), rays.begin() + 500);
  const SceneGradient g_full = loss_gradient(s, few, w, full);
  // and the full tree's own gradient is the finite difference of its value
  const float keep = s.ior;
  const double h = 1e-3;
  s.ior = float(double(keep) + h);
  const double up = loss(s, few, w, full);
  s.ior = float(double(keep) - h);
  const double down = loss(s, few, w, full);
  s.ior = keep;
  CHECK(g_full.ior[0] == doctest::Approx((up - down) / (2.0 * h)).epsilon(0.02));
}

TEST_CASE("forward and reverse mode agree") {
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.5f);
  smooth_environment(s);
  s.set_homogeneous_absorption(Vec3f(0.5f, 1.0f, 2.0f));
  TraceSettings tree;
  tree.max_depth = 6;
  TraceSettings drawn;  // one path beyond the tree of 3, to 12
  drawn.max_depth = 12;
  drawn.tree_depth = 3;
  TraceSettings roulette = drawn;
  roulette.roulette = true;
  roulette.prune_throughput = 0.05f;
  const auto rays = rays_towards_centre(Vec3f(0.2f, 0.4f, 3.0f), 0.4f, 8);
  const Vec3d w(1.0, 0.5, 0.25);
  // a direction touching every buffer
  std::vector<float> dp(s.mesh.positions.size()), de(s.environment.size()), da(s.absorption_raw.size());
  float di = 0.7f;
  for (std::size_t i = 0; i < dp.size(); ++i) dp[i] = std::sin(0.37f * float(i));
  for (std::size_t i = 0; i < de.size(); ++i) de[i] = std::cos(0.11f * float(i));
  for (std::size_t i = 0; i < da.size(); ++i) da[i] = 0.5f - float(i);
  for (const auto& [name, ts] : {std::pair<const char*, TraceSettings>{"tree", tree}, {"drawn path", drawn},
                                 {"drawn path and roulette", roulette}}) {
    CAPTURE(name);
    const SceneGradient g = loss_gradient(s, rays, w, ts);
    double reverse = di * g.ior[0];
    for (std::size_t i = 0; i < dp.size(); ++i) reverse += double(dp[i]) * g.positions[i];
    for (std::size_t i = 0; i < de.size(); ++i) reverse += double(de[i]) * g.environment[i];
    for (std::size_t i = 0; i < da.size(); ++i) reverse += double(da[i]) * g.absorption[i];
    using D = ad::Dual<double, 1>;
    ad::ParamSet params = s.params();
    params.buffers[difftrans::render::param_positions].tangents[0] = dp.data();
    params.buffers[difftrans::render::param_ior].tangents[0] = &di;
    params.buffers[difftrans::render::param_environment].tangents[0] = de.data();
    params.buffers[difftrans::render::param_absorption].tangents[0] = da.data();
    ad::ParamReader<D> reader(&params);
    double forward = 0;
    for (const auto& r : rays) {
      const Vec3<D> L = difftrans::render::trace<D>(s.view(true), s.accel(), reader, r.o, r.d, ts);
      for (int c = 0; c < 3; ++c) forward += w[c] * L[c].grad[0];
    }
    CHECK(forward == doctest::Approx(reverse).epsilon(1e-5));
  }
}

TEST_CASE("streamed reverse mode: the same gradient on a tape bounded by the depth") {
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.5f);
  smooth_environment(s);
  const auto rays = rays_towards_centre(Vec3f(0.2f, 0.4f, 3.0f), 0.45f, 12);
  const Vec3d w(0.7, 1.0, 1.3);
  for (const GradientCase& c : gradient_cases()) {
    CAPTURE(c.name);
    set_case_absorption(s, c.absorption);
    const SceneGradient full = loss_gradient(s, rays, w, c.ts);
    std::vector<Vec3d> radiance;
    std::int32_t peak = 0;
    const SceneGradient streamed = streamed_gradient(s, rays, w, c.ts, &radiance, &peak);
    // the radiance, and every gradient entry, to float rounding of the sums
    for (std::size_t i = 0; i < rays.size(); ++i)
      for (int k = 0; k < 3; ++k) CHECK(radiance[i][k] == doctest::Approx(trace_value<double>(s, rays[i], c.ts)[k]).epsilon(1e-12));
    CHECK(same_gradient(full.positions, streamed.positions, "positions") > 0.0f);
    CHECK(same_gradient(full.ior, streamed.ior, "ior") > 0.0f);
    same_gradient(full.environment, streamed.environment, "environment");
    const float absorption_scale = same_gradient(full.absorption, streamed.absorption, "absorption");
    CHECK((c.absorption == 0) == (absorption_scale == 0.0f));
    // the whole tree's tape against the streamed tape's peak
    const std::int32_t full_peak = whole_tape(s, rays, c.ts).peak;
    MESSAGE(std::string(c.name), ": largest tape ", full_peak, " nodes, streamed ", peak);
    CHECK(peak <= full_peak);  // a sphere's tree is nearly a chain: little to gain
  }
  SUBCASE("spot's bushy tree at depth 16: the largest tape shrinks from the tree to a path") {
    const SpotDeepTree spot(w);
    std::vector<Vec3d> radiance;
    std::int32_t peak = 0;
    const SceneGradient streamed = streamed_gradient(spot.scene, spot.rays, w, spot.settings, &radiance, &peak);
    CHECK(same_gradient(spot.full.positions, streamed.positions, "positions") > 0.0f);
    const std::int32_t full_peak = whole_tape(spot.scene, spot.rays, spot.settings).peak;
    MESSAGE("spot at depth 16: largest tape ", full_peak, " nodes, streamed ", peak);
    CHECK(2 * peak < full_peak);
  }
}

TEST_CASE("gradient_depth: the derivative of the tree cut at k, the deeper light held fixed") {
  // Branches deeper than k are traced off the tape and add a constant (their
  // weight included), so the gradient equals that of the same tree stopped at
  // k interactions, while the radiance is the full tree's.
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.5f);
  smooth_environment(s);
  s.set_homogeneous_absorption(Vec3f(0.5f, 1.0f, 2.0f));
  const auto rays = rays_towards_centre(Vec3f(0.2f, 0.4f, 3.0f), 0.45f, 16);
  const Vec3d w(0.7, 1.0, 1.3);
  TraceSettings full;
  full.max_depth = 8;
  for (const int k : {1, 2, 4}) {
    CAPTURE(k);
    TraceSettings gated = full, cut = full;
    gated.gradient_depth = k;
    cut.max_depth = k;
    const SceneGradient g = loss_gradient(s, rays, w, gated), g_cut = loss_gradient(s, rays, w, cut),
                        g_full = loss_gradient(s, rays, w, full);
    CHECK(g.ior[0] == doctest::Approx(g_cut.ior[0]).epsilon(1e-5));
    double worst = 0.0, scale = 0.0, differs = 0.0;
    for (std::size_t i = 0; i < g.positions.size(); ++i) {
      worst = std::max(worst, double(std::abs(g.positions[i] - g_cut.positions[i])));
      scale = std::max(scale, double(std::abs(g_cut.positions[i])));
      differs = std::max(differs, double(std::abs(g.positions[i] - g_full.positions[i])));
    }
    CHECK(worst <= 1e-5 * scale);
    CHECK(differs > 1e-3 * scale);  // the deeper branches' derivatives are left out
    for (int c = 0; c < 3; ++c) CHECK(g.absorption[std::size_t(c)] == doctest::Approx(g_cut.absorption[std::size_t(c)]).epsilon(1e-5));
    for (const auto& r : rays)  // the radiance of the whole tree
      CHECK(glm::length(trace_value<double>(s, r, gated) - trace_value<double>(s, r, full)) < 1e-12);
  }
  // k at or beyond the depth: every branch, the full gradient
  TraceSettings all = full;
  all.gradient_depth = full.max_depth;
  const SceneGradient a = loss_gradient(s, rays, w, all), b = loss_gradient(s, rays, w, full);
  CHECK(a.positions == b.positions);
  CHECK(a.ior == b.ior);
}

TEST_CASE("attenuation_path_gradient off: the absorption's derivative stays, the path lengths' goes") {
  // At IoR 1 the light runs straight through with no reflection, so the
  // vertices act on the colour only through the lengths of the segments
  // inside: without that derivative their gradient is zero; at IoR 1.5 the
  // bending and the Fresnel weights still move them. σ's gradient and the
  // radiance are the same either way.
  const auto rays = rays_towards_centre(Vec3f(0.2f, 0.4f, 3.0f), 0.45f, 16);
  const Vec3d w(0.7, 1.0, 1.3);
  TraceSettings full;
  full.max_depth = 6;
  TraceSettings fixed_paths = full;
  fixed_paths.attenuation_path_gradient = false;
  const auto largest = [](const std::vector<float>& v) {
    double m = 0.0;
    for (float x : v) m = std::max(m, double(std::abs(x)));
    return m;
  };
  for (const float ior : {1.0f, 1.5f}) {
    CAPTURE(ior);
    HostScene s = make_scene(make_icosphere(0.5f, 2), ior);
    smooth_environment(s);
    s.set_homogeneous_absorption(Vec3f(0.5f, 1.0f, 2.0f));
    const SceneGradient g = loss_gradient(s, rays, w, fixed_paths), g_full = loss_gradient(s, rays, w, full);
    const double scale = largest(g_full.positions);
    REQUIRE(scale > 0.0);
    if (ior == 1.0f) {
      CHECK(largest(g.positions) <= 1e-6 * scale);
    } else {
      CHECK(largest(g.positions) > 0.05 * scale);
      double differs = 0.0;
      for (std::size_t i = 0; i < g.positions.size(); ++i)
        differs = std::max(differs, double(std::abs(g.positions[i] - g_full.positions[i])));
      CHECK(differs > 1e-3 * scale);
    }
    for (int c = 0; c < 3; ++c)
      CHECK(g.absorption[std::size_t(c)] == doctest::Approx(g_full.absorption[std::size_t(c)]).epsilon(1e-5));
    for (const auto& r : rays)
      CHECK(glm::length(trace_value<double>(s, r, fixed_paths) - trace_value<double>(s, r, full)) < 1e-12);
  }
}

TEST_CASE("gradient_refractions: derivatives along the main refraction path only") {
  // A parallel plate at normal incidence: the main path (entry, exit) brings
  // (1 − R)² a A, every other branch adds a constant, so with
  // gradient_refractions = 2 the IoR derivative is d/dη (1 − R)² a · A alone;
  // with 0 it is that of the whole series (reflected light included).
  const double eta = 1.5, thickness = 0.2, sigma = 2.0;
  HostScene s = make_scene(make_box(5.0f, 5.0f, float(thickness / 2)), float(eta));
  const Vec3f A(1.0f, 0.5f, 0.25f), B(0.1f, 0.2f, 0.4f);
  two_sided_environment(s, A, B);
  s.set_homogeneous_absorption(Vec3f(float(sigma)));
  const std::vector<TestRay> ray{{Vec3f(0.0f, 0.0f, 2.0f), Vec3f(0.0f, 0.0f, -1.0f)}};
  const Vec3d w(0.7, 1.0, 1.3);
  TraceSettings full;
  full.max_depth = 16;
  full.smooth_normals = false;
  TraceSettings main_path = full;
  main_path.gradient_refractions = 2;
  const double a = std::exp(-sigma * thickness);
  const auto reflectance = [](double e) { return std::pow((e - 1) / (e + 1), 2); };
  const double dR = 4 * (eta - 1) / std::pow(eta + 1, 3);
  const double expected_main = -2 * (1 - reflectance(eta)) * dR * a * glm::dot(w, Vec3d(A));
  const auto series_loss = [&](double e) {
    const SlabSeries sr = slab_series(reflectance(e), a, 16);
    return sr.transmitted * glm::dot(w, Vec3d(A)) + sr.reflected * glm::dot(w, Vec3d(B));
  };
  const double h = 1e-5, expected_full = (series_loss(eta + h) - series_loss(eta - h)) / (2 * h);
  const SceneGradient g_main = loss_gradient(s, ray, w, main_path);
  const SceneGradient g_full = loss_gradient(s, ray, w, full);
  CAPTURE(expected_main);
  CAPTURE(expected_full);
  CHECK(g_main.ior[0] == doctest::Approx(expected_main).epsilon(1e-4));
  CHECK(g_full.ior[0] == doctest::Approx(expected_full).epsilon(1e-4));
  CHECK(std::abs(expected_main - expected_full) > 0.05 * std::abs(expected_full));  // the two differ
  // the radiance is the same whichever branches carry derivatives
  CHECK(glm::length(trace_value<double>(s, ray[0], main_path) - trace_value<double>(s, ray[0], full)) < 1e-12);

  // a glass sphere: forward and reverse mode agree on the main-path
  // derivatives, the same values come out, and the tape is shorter
  HostScene sp = make_scene(make_icosphere(0.5f, 2), 1.5f);
  smooth_environment(sp);
  sp.set_homogeneous_absorption(Vec3f(0.5f, 1.0f, 2.0f));
  TraceSettings ts;
  ts.max_depth = 8;
  ts.gradient_refractions = 2;
  const auto rays = rays_towards_centre(Vec3f(0.2f, 0.4f, 3.0f), 0.4f, 8);
  const SceneGradient g = loss_gradient(sp, rays, w, ts);
  TraceSettings every = ts;
  every.gradient_refractions = 0;
  const SceneGradient g_every = loss_gradient(sp, rays, w, every);
  std::vector<float> dp(sp.mesh.positions.size());
  for (std::size_t i = 0; i < dp.size(); ++i) dp[i] = std::sin(0.37f * float(i));
  float di = 0.7f;
  double reverse = di * g.ior[0], reverse_every = di * g_every.ior[0];
  for (std::size_t i = 0; i < dp.size(); ++i) {
    reverse += double(dp[i]) * g.positions[i];
    reverse_every += double(dp[i]) * g_every.positions[i];
  }
  using D = ad::Dual<double, 1>;
  ad::ParamSet params = sp.params();
  params.buffers[difftrans::render::param_positions].tangents[0] = dp.data();
  params.buffers[difftrans::render::param_ior].tangents[0] = &di;
  ad::ParamReader<D> reader(&params);
  double forward = 0;
  for (const auto& r : rays) {
    const Vec3<D> L = difftrans::render::trace<D>(sp.view(true), sp.accel(), reader, r.o, r.d, ts);
    for (int c = 0; c < 3; ++c) forward += w[c] * L[c].grad[0];
  }
  CHECK(forward == doctest::Approx(reverse).epsilon(1e-5));
  CHECK(std::abs(reverse - reverse_every) > 1e-3 * std::abs(reverse_every));
  // tape nodes per ray
  const auto nodes = [&](const TraceSettings& settings) {
    const WholeTape t = whole_tape(sp, rays, settings);
    for (std::size_t i = 0; i < rays.size(); ++i)
      CHECK(std::abs(t.radiance[i].x - trace_value<double>(sp, rays[i], every).x) < 1e-12);
    return t.total;
  };
  const std::int64_t n_main = nodes(ts), n_every = nodes(every);
  MESSAGE("tape nodes over 8 sphere rays: main path " << n_main << ", every branch " << n_every);
  CHECK(n_main < n_every / 2);
}

TEST_CASE("two-level normals give the one-ring gradient") {
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.5f);
  smooth_environment(s);
  TraceSettings ts;
  ts.max_depth = 5;
  const auto rays = rays_towards_centre(Vec3f(0.2f, 0.4f, 3.0f), 0.4f, 12);
  s.two_level_normals = true;
  const SceneGradient two_level = loss_gradient(s, rays, Vec3d(1.0, 0.6, 0.3), ts);
  s.two_level_normals = false;
  const SceneGradient one_ring = loss_gradient(s, rays, Vec3d(1.0, 0.6, 0.3), ts);
  double diff = 0, norm = 0;
  for (std::size_t i = 0; i < one_ring.positions.size(); ++i) {
    diff += std::pow(double(two_level.positions[i]) - one_ring.positions[i], 2);
    norm += std::pow(double(one_ring.positions[i]), 2);
  }
  CHECK(norm > 0);
  CHECK(std::sqrt(diff / norm) < 1e-5);
  CHECK(two_level.ior[0] == doctest::Approx(one_ring.ior[0]).epsilon(1e-6));
}

// ---------------------------------------------------------------- near-field escapes

namespace {

// A field over [-3, 3]³ with varied colour, dense near the box's faces and thin inside.
std::shared_ptr<difftrans::scene::RadianceField> wall_field() {
  auto f = std::make_shared<difftrans::scene::RadianceField>(Vec3i(12), Vec3f(-3.0f), Vec3f(3.0f), -6.0f, 0.0f);
  for (int k = 0; k < 12; ++k)
    for (int j = 0; j < 12; ++j)
      for (int i = 0; i < 12; ++i) {
        float* v = f->values.data() + ((std::size_t(k) * 12 + j) * 12 + i) * 4;
        const bool face = i == 0 || i == 11 || j == 0 || j == 11 || k == 0 || k == 11;
        v[0] = face ? 4.0f : -6.0f;
        v[1] = -1.0f + 0.2f * float(i);
        v[2] = 1.0f - 0.15f * float(j);
        v[3] = -0.5f + 0.1f * float(k + i);
      }
  f->update_occupancy(1e-3f);
  return f;
}

// Records where the tracer asked for the environment, then answers as the field would.
struct RecordingEscape {
  difftrans::scene::RadianceFieldView field;
  std::vector<std::pair<Vec3f, Vec3f>>* calls;
  template <class S, class Reader>
  Vec3<S> operator()(Reader&, const difftrans::render::SceneView&, const Vec3<S>& o, const Vec3<S>& d) const {
    calls->emplace_back(Vec3f(value_of(o)), Vec3f(value_of(d)));
    const Vec3f L = difftrans::scene::field_radiance<float>(field, Vec3f(value_of(o)), Vec3f(value_of(d)));
    return Vec3<S>(S(L.x), S(L.y), S(L.z));
  }
};

}  // namespace

TEST_CASE("near-field escape: rays that miss read the field at their own origin and direction") {
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.5f);
  smooth_environment(s);
  const auto field = wall_field();
  s.set_near_field(field);
  const auto cam = difftrans::scene::look_at_camera(Vec3f(0.4f, 0.3f, 2.0f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, 20, 16);
  const std::vector<float> img = difftrans::render::render_image(s, cam);
  int missed = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const auto r = cam.generate_ray(x, y);
      if (s.accel().intersect(r.origin, r.direction).hit()) continue;
      ++missed;
      const Vec3f want = difftrans::scene::field_radiance<float>(field->view(), r.origin, r.direction);
      for (int c = 0; c < 3; ++c) CHECK(img[(std::size_t(y) * cam.width + x) * 3 + c] == want[c]);
    }
  CHECK(missed > 50);
  // the same scene without the field reads the distant map instead
  s.set_near_field(nullptr);
  const std::vector<float> distant = difftrans::render::render_image(s, cam);
  CHECK(distant != img);
}

TEST_CASE("near-field escape: every escaping branch reads the field at its origin and direction") {
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.5f);
  const auto field = wall_field();
  s.set_near_field(field);
  TraceSettings ts;
  ts.max_depth = 6;
  const ad::ParamSet params = s.params();
  ad::ParamReader<double> reader(&params);
  for (const TestRay& r : rays_towards_centre(Vec3f(0.2f, 0.4f, 2.5f), 0.4f, 6)) {
    std::vector<std::pair<Vec3f, Vec3f>> calls;
    TraceStats st;
    const Vec3d recorded = difftrans::render::trace<double>(s.view(false), s.accel(), reader, r.o, r.d, ts, &st,
                                                            RecordingEscape{field->view(), &calls});
    const Vec3d fixed = difftrans::render::trace<double>(
        s.view(false), s.accel(), reader, r.o, r.d, ts, nullptr,
        difftrans::render::fixed_escape(difftrans::scene::FieldRadiance{field->view()}));
    for (int c = 0; c < 3; ++c) CHECK(fixed[c] == recorded[c]);
    // the branches that escape start on the object's surface (not at the camera) and point outwards
    REQUIRE(calls.size() >= 2);
    for (const auto& call : calls) {
      CHECK(glm::length(call.first) == doctest::Approx(0.5).epsilon(0.03));
      CHECK(glm::dot(call.first, call.second) > 0.0f);
    }
  }
}

TEST_CASE("near-field escape: with IoR 1 the room is seen straight through the object") {
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.0f);
  difftrans::scene::Room room;
  room.half = 3.0f;
  const auto cam = difftrans::scene::look_at_camera(Vec3f(0.3f, 0.5f, 2.0f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, 24, 24);
  const std::vector<float> img =
      difftrans::render::render_image_with<float>(s, cam, difftrans::render::PassOptions{}, difftrans::render::fixed_escape(room));
  int agree = 0, through = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const auto r = cam.generate_ray(x, y);
      through += s.accel().intersect(r.origin, r.direction).hit();
      const Vec3f want = room.radiance(r.origin, r.direction);
      bool same = true;
      for (int c = 0; c < 3; ++c) same = same && std::abs(img[(std::size_t(y) * cam.width + x) * 3 + c] - want[c]) < 1e-5f;
      agree += same;
    }
  CHECK(through > 100);
  // a pixel may flip only where its ray grazes a pattern edge within float error
  CHECK(agree >= cam.width * cam.height - 2);
}

TEST_CASE("near-field escape: the gradient pass runs with a field and leaves the distant texels alone") {
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.5f);
  smooth_environment(s);
  s.set_near_field(wall_field());
  const auto cam = difftrans::scene::look_at_camera(Vec3f(0.4f, 0.3f, 2.0f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.6f, 12, 12);
  std::vector<float> adjoint(12 * 12 * 3, 1.0f);
  SceneGradient g(s);
  const std::vector<float> img = difftrans::render::render_gradient(s, cam, adjoint.data(), g);
  const std::vector<float> plain = difftrans::render::render_image(s, cam);
  for (std::size_t i = 0; i < img.size(); ++i) CHECK(img[i] == doctest::Approx(plain[i]).epsilon(1e-6));
  for (float v : g.environment) CHECK(v == 0.0f);
  CHECK(std::isfinite(g.ior[0]));
  CHECK(g.ior[0] != 0.0f);
  double norm = 0;
  for (float v : g.positions) norm += double(v) * v;
  CHECK(std::isfinite(norm));
  CHECK(norm > 0.0);
}

TEST_CASE("triangle records: the tracer's radiance and IoR derivative are those of the mesh arrays") {
  // A torus (rays that leave and re-enter) and a sphere through a grid, with
  // the Fresnel tree, a drawn path and roulette: every hit of the passes that
  // read the positions as constants comes from scene::TriangleRecord, and
  // must give what the arrays give.
  for (const bool torus : {false, true}) {
    CAPTURE(torus);
    HostScene s = make_scene(torus ? make_torus(24, 12, 0.6f, 0.25f) : make_icosphere(0.5f, 3), 1.5f);
    smooth_environment(s);
    set_case_absorption(s, 2);
    s.mesh.positions[4] += 0.01f;  // a vertex moved, then the normals, records and BVH remade
    s.positions_changed();
    for (const GradientCase& gc : gradient_cases()) {
      CAPTURE(gc.name);
      const render::SceneView with = s.view(false);
      REQUIRE(with.mesh.records != nullptr);
      render::SceneView without = with;
      without.mesh.records = nullptr;
      // d/dIoR by a Dual: the positions stay constants, so the records are read too
      for (bool& d : s.differentiate) d = false;
      s.differentiate[render::param_ior] = true;
      const render::SceneView dual_with = s.view(true);
      for (bool& d : s.differentiate) d = true;
      REQUIRE(dual_with.mesh.records != nullptr);
      render::SceneView dual_without = dual_with;
      dual_without.mesh.records = nullptr;
      ad::ParamSet params = s.params();
      const float one = 1.0f;
      params.buffers[render::param_ior].tangents[0] = &one;
      ad::ParamReader<float> reader(&params);
      ad::ParamReader<ad::Dual<float, 1>> dual_reader(&params);
      int segments = 0, derivatives = 0;
      for (const TestRay& r : rays_towards_centre(Vec3f(0.3f, 0.4f, 2.5f), 0.7f, 40)) {
        TraceStats a, b;
        const Vec3f La = render::trace<float>(with, s.accel(), reader, r.o, r.d, gc.ts, &a);
        const Vec3f Lb = render::trace<float>(without, s.accel(), reader, r.o, r.d, gc.ts, &b);
        CHECK(La == Lb);
        CHECK(a.segments == b.segments);
        segments += a.segments;
        const auto Da = render::trace<ad::Dual<float, 1>>(dual_with, s.accel(), dual_reader, r.o, r.d, gc.ts);
        const auto Db = render::trace<ad::Dual<float, 1>>(dual_without, s.accel(), dual_reader, r.o, r.d, gc.ts);
        for (int c = 0; c < 3; ++c) {
          CHECK(Da[c].value == Db[c].value);
          CHECK(Da[c].grad[0] == Db[c].grad[0]);
          derivatives += Da[c].grad[0] != 0.0f;
        }
      }
      CHECK(segments > 40 * 3);
      CHECK(derivatives > 40);
    }
  }
}
