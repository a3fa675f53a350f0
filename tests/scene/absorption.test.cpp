// Absorption field: homogeneous closed form; the grid's exact cell-by-cell
// integral against closed forms (linear and cubic fields) and an independent
// fine quadrature; K-sample quadrature converging to it; boundary, axis,
// zero-length, outside and huge-absorption segments; derivatives with respect
// to the raw grid parameters and the segment ends; forward against reverse.
#include "scene/scene_check.hpp"

#include <cstdint>
#include <cstring>
#include <utility>
#include <vector>

using namespace dt_test;
using scene::AbsorptionField;
using scene::AbsorptionIntegration;

namespace {

double softplus_d(double x) { return std::max(x, 0.0) + std::log1p(std::exp(-std::abs(x))); }
double inverse_softplus_d(double s) { return s > 30 ? s + std::log(-std::expm1(-s)) : std::log(std::expm1(s)); }

const Vec3i kRes(4, 5, 3);
const Vec3f kLo(-0.5f, -0.4f, -0.6f), kHi(0.7f, 0.6f, 0.5f);

struct Grid {
  std::vector<std::vector<double>> values;
  AbsorptionField field;
  Grid(const Vec3i& res, const Vec3f& lo, const Vec3f& hi, std::vector<double> raw)
      : values{std::move(raw)}, field(scene::grid_absorption(nullptr, res, lo, hi, 0)) {}
};

Grid random_grid(unsigned seed = 21) {
  return Grid(kRes, kLo, kHi, uniform_values(std::size_t(kRes.x * kRes.y * kRes.z * 3), -1.0, 2.0, seed));
}

// Independent reference: sigma at x by its own trilinear interpolation.
double sigma_ref(const Grid& g, const Vec3d& x, int ch) {
  const AbsorptionField& f = g.field;
  Vec3d l;
  int i0[3];
  for (int a = 0; a < 3; ++a) {
    if (x[a] < f.lo[a] || x[a] > f.hi[a]) return 0.0;
    const double c = (x[a] - f.lo[a]) / (double(f.hi[a]) - f.lo[a]) * (f.res[a] - 1);
    i0[a] = std::min(int(std::floor(c)), f.res[a] - 2);
    l[a] = c - i0[a];
  }
  double s = 0.0;
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        const double w = (dx ? l.x : 1 - l.x) * (dy ? l.y : 1 - l.y) * (dz ? l.z : 1 - l.z);
        const std::int32_t idx = scene::grid_index(f.res, i0[0] + dx, i0[1] + dy, i0[2] + dz, ch);
        s += w * softplus_d(g.values[0][std::size_t(idx)]);
      }
  return s;
}

// Independent reference: the part of [a, b] inside the box, then a fine midpoint rule.
double depth_ref(const Grid& g, const Vec3d& a, const Vec3d& b, int ch, int n = 4000) {
  double t0 = 0.0, t1 = 1.0;
  for (int ax = 0; ax < 3; ++ax) {
    const double d = b[ax] - a[ax];
    if (d == 0.0) {
      if (a[ax] < g.field.lo[ax] || a[ax] > g.field.hi[ax]) return 0.0;
      continue;
    }
    const double ta = (g.field.lo[ax] - a[ax]) / d, tb = (g.field.hi[ax] - a[ax]) / d;
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  }
  if (t1 <= t0) return 0.0;
  const double h = (t1 - t0) / n;
  double s = 0.0;
  for (int k = 0; k < n; ++k) {
    const double t = t0 + (k + 0.5) * h;
    Vec3d x = a + t * (b - a);
    for (int ax = 0; ax < 3; ++ax)  // stay inside against rounding at the faces
      x[ax] = std::min(std::max(x[ax], double(g.field.lo[ax])), double(g.field.hi[ax]));
    s += sigma_ref(g, x, ch);
  }
  return s * h * glm::length(b - a);
}

template <class S, class Reader>
Vec3<S> depth(Reader& r, const AbsorptionField& f, const Vec3d& a, const Vec3d& b, AbsorptionIntegration q = {}) {
  return scene::optical_depth(r, f, Vec3<S>(S(a.x), S(a.y), S(a.z)), Vec3<S>(S(b.x), S(b.y), S(b.z)), q);
}

std::vector<std::pair<Vec3d, Vec3d>> random_segments(int n, unsigned seed, double extent) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  std::vector<std::pair<Vec3d, Vec3d>> s;
  for (int k = 0; k < n; ++k) s.push_back({Vec3d(u(rng), u(rng), u(rng)), Vec3d(u(rng), u(rng), u(rng))});
  return s;
}

}  // namespace

TEST_CASE_TEMPLATE("homogeneous: closed-form exp(-softplus(p) d)", S, DT_ALL_SCALARS) {
  const std::vector<std::vector<double>> values{{0.3, -1.2, 2.0}};
  const AbsorptionField f = scene::homogeneous_absorption(nullptr, 0);
  OverrideReader<S> r{&values};
  const Vec3d a(0.1, -0.2, 0.3), b(-0.4, 0.5, 0.05);
  const double d = glm::length(b - a);
  const Vec3<S> T = scene::transmittance(r, f, Vec3<S>(S(a.x), S(a.y), S(a.z)), Vec3<S>(S(b.x), S(b.y), S(b.z)));
  for (int ch = 0; ch < 3; ++ch)
    CHECK(close(double(ad::value_of(T[ch])), std::exp(-softplus_d(values[0][std::size_t(ch)]) * d), tol<S>()));
  // clear glass
  const Vec3<S> one = scene::transmittance(r, scene::no_absorption(), Vec3<S>(S(0), S(0), S(0)), Vec3<S>(S(1), S(1), S(1)));
  CHECK(double(ad::value_of(one.y)) == 1.0);
}

TEST_CASE("raw_from_sigma inverts softplus") {
  for (float s : {1e-3f, 0.4f, 4.0f, 50.0f, 1e4f}) CHECK(close(softplus_d(scene::raw_from_sigma(s)), s, 1e-6));
  CHECK(std::isfinite(scene::raw_from_sigma(0.0f)));
  CHECK(softplus_d(scene::raw_from_sigma(0.0f)) < 1e-7);
}

TEST_CASE("sigma_at: softplus of the raw values at the vertices, zero outside the box") {
  const Grid g = random_grid();
  OverrideReader<double> r{&g.values};
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 100; ++k) {
    const Vec3d x(u(rng), u(rng), u(rng));
    const Vec3d s = scene::sigma_at(r, g.field, x);
    for (int ch = 0; ch < 3; ++ch) CHECK(close(s[ch], sigma_ref(g, x, ch), 1e-12));
  }
  const Vec3d v = scene::sigma_at(r, g.field, Vec3d(kLo) + (Vec3d(kHi) - Vec3d(kLo)) * Vec3d(1.0 / 3, 0.5, 1.0));
  CHECK(close(v.y, softplus_d(g.values[0][std::size_t(scene::grid_index(kRes, 1, 2, 2, 1))]), 1e-12));
}

TEST_CASE("exact integration against an independent fine quadrature") {
  const Grid g = random_grid();
  OverrideReader<double> r{&g.values};
  for (const auto& [a, b] : random_segments(30, 5, 1.0)) {
    const Vec3d tau = depth<double>(r, g.field, a, b);
    for (int ch = 0; ch < 3; ++ch) {
      CAPTURE(a);
      CAPTURE(b);
      CHECK(close(tau[ch], depth_ref(g, a, b, ch), 1e-7));
    }
    const Vec3d back = depth<double>(r, g.field, b, a);  // direction does not matter
    for (int ch = 0; ch < 3; ++ch) CHECK(close(back[ch], tau[ch], 1e-12));
  }
}

TEST_CASE_TEMPLATE("exact integration reproduces a linear field's closed form", S, float, double) {
  // sigma_c(x) = alpha_c + beta_c . x is trilinear, so the grid holds it exactly
  const Vec3d alpha(2.0, 1.0, 3.0);
  const Vec3d beta[3] = {{0.5, -0.3, 0.2}, {0.1, 0.2, 0.3}, {-1.0, 0.7, -0.4}};
  std::vector<double> raw(std::size_t(kRes.x * kRes.y * kRes.z * 3));
  for (int k = 0; k < kRes.z; ++k)
    for (int j = 0; j < kRes.y; ++j)
      for (int i = 0; i < kRes.x; ++i) {
        const Vec3d x = Vec3d(kLo) + (Vec3d(kHi) - Vec3d(kLo)) * Vec3d(double(i) / (kRes.x - 1), double(j) / (kRes.y - 1),
                                                              double(k) / (kRes.z - 1));
        for (int ch = 0; ch < 3; ++ch)
          raw[std::size_t(scene::grid_index(kRes, i, j, k, ch))] = inverse_softplus_d(alpha[ch] + glm::dot(beta[ch], x));
      }
  const Grid g(kRes, kLo, kHi, raw);
  OverrideReader<S> r{&g.values};
  for (const auto& [a, b] : random_segments(20, 8, 0.39)) {  // inside the box
    const Vec3<S> tau = depth<S>(r, g.field, a, b);
    const double L = glm::length(b - a);
    for (int ch = 0; ch < 3; ++ch)
      CHECK(close(double(ad::value_of(tau[ch])), L * (alpha[ch] + glm::dot(beta[ch], 0.5 * (a + b))), tol<S>()));
  }
}

TEST_CASE("exact integration reproduces a cubic (x y z) field's closed form") {
  // one cell over the unit box: sigma = c + s x y z, a cubic along any line
  const double c = 0.5, s = 3.0;
  std::vector<double> raw(8 * 3, inverse_softplus_d(c));
  for (int ch = 0; ch < 3; ++ch) raw[std::size_t(scene::grid_index(Vec3i(2), 1, 1, 1, ch))] = inverse_softplus_d(c + s);
  const Grid g(Vec3i(2), Vec3f(0.0f), Vec3f(1.0f), raw);
  OverrideReader<double> r{&g.values};
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 20; ++k) {
    const Vec3d a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), d = b - a;
    // integral over t in [0, 1] of (a.x + t d.x)(a.y + t d.y)(a.z + t d.z)
    const double c0 = a.x * a.y * a.z;
    const double c1 = d.x * a.y * a.z + a.x * d.y * a.z + a.x * a.y * d.z;
    const double c2 = d.x * d.y * a.z + d.x * a.y * d.z + a.x * d.y * d.z;
    const double c3 = d.x * d.y * d.z;
    const double expect = glm::length(d) * (c + s * (c0 + c1 / 2 + c2 / 3 + c3 / 4));
    CHECK(close(depth<double>(r, g.field, a, b).z, expect, 1e-12));
  }
}

TEST_CASE("K-sample quadrature converges to the exact integral") {
  const Grid g = random_grid();
  OverrideReader<double> r{&g.values};
  const auto segments = random_segments(20, 9, 1.0);
  // the midpoint rule (offset 0.5) is second order, any other fixed offset first order
  for (float offset : {0.5f, 0.13f}) {
    const double factor = offset == 0.5f ? 1.0 / 8 : 1.0 / 2;
    double previous = 0.0;
    for (int K : {2, 8, 32, 128, 512}) {
      double err = 0.0;
      for (const auto& [a, b] : segments) {
        const Vec3d exact = depth<double>(r, g.field, a, b);
        const Vec3d q = depth<double>(r, g.field, a, b, AbsorptionIntegration{K, offset});
        for (int ch = 0; ch < 3; ++ch) err += std::abs(q[ch] - exact[ch]);
      }
      CAPTURE(offset);
      CAPTURE(K);
      CHECK(err > 0.0);
      if (K > 2) CHECK(err < factor * previous);  // 4x more samples
      previous = err;
    }
    CHECK(previous < (offset == 0.5f ? 1e-4 : 1e-2));
  }
}

TEST_CASE_TEMPLATE("optical_depth_share: shares over a split of the samples add up to the sampled optical depth, "
                   "derivatives too",
                   S, DT_ALL_SCALARS) {
  const Grid g = random_grid();
  OverrideReader<S> r{&g.values};
  const AbsorptionIntegration q{4, 0.37f};
  // segments inside, crossing and outside the box; one of zero length
  auto segments = random_segments(12, 5, 1.0);
  segments.push_back({Vec3d(0.1, 0.2, -0.1), Vec3d(0.1, 0.2, -0.1)});
  segments.push_back({Vec3d(1.0, 1.0, 1.0), Vec3d(2.0, 1.5, 1.0)});
  for (const auto& [a, b] : segments) {
    Vec3<S> as(S(a.x), S(a.y), S(a.z)), bs(S(b.x), S(b.y), S(b.z));
    constexpr int lanes = ad::dual_lanes<S>::value;
    if constexpr (lanes > 0)  // lane l moves coordinate l of the ends (a's, then b's)
      for (int l = 0; l < lanes && l < 6; ++l) (l < 3 ? as : bs)[l % 3].grad[l] = 1;
    const Vec3<S> whole = scene::optical_depth(r, g.field, as, bs, q);
    // one sample at a time, and split as [0, 1), [1, 3), [3, 4)
    Vec3<S> by_sample(S(0), S(0), S(0)), by_split = by_sample;
    for (int k = 0; k < q.samples; ++k) by_sample += scene::optical_depth_share(r, g.field, as, bs, q, k, k + 1);
    const int split[] = {0, 1, 3, 4};
    for (int i = 0; i < 3; ++i) by_split += scene::optical_depth_share(r, g.field, as, bs, q, split[i], split[i + 1]);
    for (const Vec3<S>& sum : {by_sample, by_split})
      for (int ch = 0; ch < 3; ++ch) {
        CHECK(close(double(ad::value_of(sum[ch])), double(ad::value_of(whole[ch])), tol<S>()));
        if constexpr (lanes > 0)
          for (int l = 0; l < lanes; ++l) CHECK(close(double(sum[ch].grad[l]), double(whole[ch].grad[l]), tol<S>()));
      }
    // empty or out of range, exact integration, or no grid: nothing
    for (const auto& [first, end] : {std::pair<int, int>{-1, 1}, {2, 2}, {3, q.samples + 1}})
      CHECK(double(ad::value_of(scene::optical_depth_share(r, g.field, as, bs, q, first, end).x)) == 0.0);
    CHECK(double(ad::value_of(scene::optical_depth_share(r, g.field, as, bs, AbsorptionIntegration{}, 0, 1).y)) ==
          0.0);
    CHECK(double(ad::value_of(
              scene::optical_depth_share(r, scene::homogeneous_absorption(nullptr, 0), as, bs, q, 0, 4).z)) == 0.0);
  }
}

TEST_CASE("segments along cell boundaries, parallel to axes and through grid vertices") {
  const Grid g = random_grid(31);
  OverrideReader<double> r{&g.values};
  const auto vertex = [&](int i, int j, int k) {
    return Vec3d(kLo) + (Vec3d(kHi) - Vec3d(kLo)) * Vec3d(double(i) / (kRes.x - 1), double(j) / (kRes.y - 1), double(k) / (kRes.z - 1));
  };
  const auto sig = [&](int i, int j, int k, int ch) {
    return softplus_d(g.values[0][std::size_t(scene::grid_index(kRes, i, j, k, ch))]);
  };
  // along a grid edge line (y, z on grid planes): the field is linear between
  // vertices, so the integral is the trapezoid sum
  for (int j : {0, 2, kRes.y - 1})
    for (int k : {0, 1, kRes.z - 1}) {
      const Vec3d tau = depth<double>(r, g.field, vertex(0, j, k), vertex(kRes.x - 1, j, k));
      const double h = glm::length(vertex(1, j, k) - vertex(0, j, k));
      for (int ch = 0; ch < 3; ++ch) {
        double trap = 0.0;
        for (int i = 0; i + 1 < kRes.x; ++i) trap += 0.5 * h * (sig(i, j, k, ch) + sig(i + 1, j, k, ch));
        CHECK(close(tau[ch], trap, 1e-12));
      }
    }
  // in a grid plane, diagonal; through grid vertices; axis-parallel inside cells
  const std::pair<Vec3d, Vec3d> special[] = {
      {vertex(0, 2, 0), vertex(3, 2, 2)},            // in the plane y = y_2
      {vertex(0, 0, 0), vertex(3, 4, 2)},            // corner to corner
      {vertex(1, 1, 1), vertex(2, 2, 1)},            // through vertices, in a plane
      {Vec3d(-0.45, 0.1, 0.2), Vec3d(0.65, 0.1, 0.2)},  // parallel to x
      {Vec3d(0.1, -0.4, 0.2), Vec3d(0.1, 0.6, 0.2)},    // parallel to y, box face to face
      {Vec3d(0.1, 0.3, -2.0), Vec3d(0.1, 0.3, 2.0)},    // parallel to z, through the whole box
      {Vec3d(kLo.x, 0.1, 0.2), Vec3d(kLo.x, 0.3, -0.2)},  // on a box face
  };
  for (const auto& [a, b] : special) {
    const Vec3d tau = depth<double>(r, g.field, a, b);
    for (int ch = 0; ch < 3; ++ch) {
      CAPTURE(a);
      CAPTURE(b);
      CHECK(close(tau[ch], depth_ref(g, a, b, ch, 20000), 1e-7));
    }
  }
}

TEST_CASE_TEMPLATE("zero-length and outside segments", S, DT_ALL_SCALARS) {
  const Grid g = random_grid();
  OverrideReader<S> r{&g.values};
  const Vec3d p(0.1, 0.2, -0.1);
  const Vec3<S> z = depth<S>(r, g.field, p, p);
  for (int ch = 0; ch < 3; ++ch) CHECK(double(ad::value_of(z[ch])) == 0.0);
  const Vec3<S> T = scene::transmittance(r, g.field, Vec3<S>(S(p.x), S(p.y), S(p.z)), Vec3<S>(S(p.x), S(p.y), S(p.z)));
  CHECK(double(ad::value_of(T.x)) == 1.0);
  // entirely outside the box, also parallel to a face
  for (const auto& [a, b] : {std::pair<Vec3d, Vec3d>{{1.0, 1.0, 1.0}, {2.0, 1.5, 1.0}},
                             std::pair<Vec3d, Vec3d>{{-1.0, 0.7, 0.0}, {1.0, 0.7, 0.0}},
                             std::pair<Vec3d, Vec3d>{{-2.0, 0.0, 0.0}, {-0.6, 0.0, 0.0}}}) {
    const Vec3<S> o = depth<S>(r, g.field, a, b);
    for (int ch = 0; ch < 3; ++ch) CHECK(double(ad::value_of(o[ch])) == 0.0);
  }
  // partly outside: the same as the inside part
  const Vec3d a(-1.5, 0.1, 0.0), b(1.5, 0.1, 0.0);
  const Vec3<S> part = depth<S>(r, g.field, a, b);
  const Vec3<S> inside = depth<S>(r, g.field, Vec3d(kLo.x, 0.1, 0.0), Vec3d(kHi.x, 0.1, 0.0));
  for (int ch = 0; ch < 3; ++ch)
    CHECK(close(double(ad::value_of(part[ch])), double(ad::value_of(inside[ch])), tol<S>()));
}

TEST_CASE_TEMPLATE("zero-length segments have finite (zero) derivatives", S, DT_AD_SCALARS) {
  const Grid g = random_grid();
  const Vec3d p(0.1, 0.2, -0.1);
  for (const AbsorptionField& f : {g.field, scene::homogeneous_absorption(nullptr, 0)}) {
    for (int comp = 0; comp < 6; ++comp) {
      const double d = derivative<S>(
          [&](auto x) {
            using R = decltype(x);
            OverrideReader<R> r{&g.values};
            Vec3<R> a(R(p.x), R(p.y), R(p.z)), b = a;
            (comp < 3 ? a : b)[comp % 3] = x;
            return scene::transmittance(r, f, a, b)[1];
          },
          p[comp % 3]);
      CHECK(std::isfinite(d));
      CHECK(d == 0.0);
    }
    const double dp = param_derivative<S>(g.values, 0, 4, [&](auto& r) {
      using R = decltype(r.x);
      return scene::optical_depth(r, f, Vec3<R>(R(p.x), R(p.y), R(p.z)), Vec3<R>(R(p.x), R(p.y), R(p.z)))[1];
    });
    CHECK(dp == 0.0);
  }
}

TEST_CASE_TEMPLATE("huge absorption: transmittance 0, values and derivatives finite", S, DT_AD_SCALARS) {
  for (double raw : {1e6, 1e30}) {
    const std::size_t n = std::size_t(kRes.x * kRes.y * kRes.z * 3);
    const Grid g(kRes, kLo, kHi, std::vector<double>(n, raw));
    const std::vector<std::vector<double>> hv{{raw, raw, raw}};
    const AbsorptionField hom = scene::homogeneous_absorption(nullptr, 0);
    for (int mode = 0; mode < 3; ++mode) {
      const AbsorptionField& f = mode == 2 ? hom : g.field;
      const auto& values = mode == 2 ? hv : g.values;
      const AbsorptionIntegration q{mode == 1 ? 5 : 0, 0.5f};
      const Vec3d a(-0.3, 0.1, 0.2), b(0.4, -0.2, 0.0);
      for (int comp = 0; comp < 6; ++comp) {
        CAPTURE(raw);
        CAPTURE(mode);
        CAPTURE(comp);
        double value = -1;
        const double d = derivative<S>(
            [&](auto x) {
              using R = decltype(x);
              OverrideReader<R> r{&values};
              Vec3<R> ra(R(a.x), R(a.y), R(a.z)), rb(R(b.x), R(b.y), R(b.z));
              (comp < 3 ? ra : rb)[comp % 3] = x;
              return scene::transmittance(r, f, ra, rb, q)[0];
            },
            (comp < 3 ? a : b)[comp % 3], &value);
        CHECK(value == 0.0);
        CHECK(std::isfinite(d));
      }
      double value = -1;
      const double dp = param_derivative<S>(
          values, 0, 2,
          [&](auto& r) {
            using R = decltype(r.x);
            return scene::transmittance(r, f, Vec3<R>(R(a.x), R(a.y), R(a.z)), Vec3<R>(R(b.x), R(b.y), R(b.z)), q)[2];
          },
          &value);
      CHECK(value == 0.0);
      CHECK(std::isfinite(dp));
    }
  }
}

TEST_CASE_TEMPLATE("derivatives with respect to raw parameters and segment ends match central differences", S,
                   DT_AD_SCALARS) {
  const Grid g = random_grid();
  const std::pair<Vec3d, Vec3d> segments[] = {
      // ends off the cell faces (there the derivative has a kink and central
      // differences are only first-order accurate)
      {{-0.3, 0.12, 0.2}, {0.5, -0.2, -0.1}},    // inside, several cells
      {{-0.9, -0.1, 0.05}, {0.33, 0.25, -0.3}},  // enters through a box face: the clipped end moves
      {{0.1, 0.5, -0.55}, {0.12, 0.52, -0.1}},  // short, near a corner
  };
  const AbsorptionIntegration modes[] = {{0, 0.5f}, {7, 0.3f}};
  for (const AbsorptionIntegration& q : modes) {
    for (const auto& [a, b] : segments) {
      for (int ch = 0; ch < 3; ++ch) {
        const auto tau_of = [&](auto& r) {
          using R = decltype(r.x);
          return scene::transmittance(r, g.field, Vec3<R>(R(a.x), R(a.y), R(a.z)), Vec3<R>(R(b.x), R(b.y), R(b.z)), q)[ch];
        };
        int touched = 0;
        for (std::int32_t i = ch; i < std::int32_t(g.values[0].size()); i += 3) {
          CAPTURE(q.samples);
          CAPTURE(a);
          CAPTURE(i);
          const double d = param_derivative<S>(g.values, 0, i, tau_of);
          const double fd = param_difference(g.values, 0, i, tau_of);
          CHECK(std::abs(d - fd) <= tol<S>() * 10 * std::max(1.0, std::abs(fd)));
          touched += d != 0.0;
        }
        CHECK(touched > 0);
        for (int comp = 0; comp < 6; ++comp) {
          CAPTURE(q.samples);
          CAPTURE(a);
          CAPTURE(comp);
          const auto f = [&](auto x) {
            using R = decltype(x);
            OverrideReader<R> r{&g.values};
            Vec3<R> ra(R(a.x), R(a.y), R(a.z)), rb(R(b.x), R(b.y), R(b.z));
            (comp < 3 ? ra : rb)[comp % 3] = x;
            return scene::transmittance(r, g.field, ra, rb, q)[ch];
          };
          const double x0 = (comp < 3 ? a : b)[comp % 3];
          const double d = derivative<S>(f, x0);
          const double fd = central_difference(f, x0);
          CHECK(std::abs(d - fd) <= tol<S>() * 10 * std::max(1.0, std::abs(fd)));
        }
      }
    }
  }
}

TEST_CASE("forward and reverse mode agree through the library's readers") {
  const std::vector<float> raw = to_float(uniform_values(std::size_t(kRes.x * kRes.y * kRes.z * 3), -1.0, 2.0, 77));
  for (int samples : {0, 6}) {
    const AbsorptionField f = scene::grid_absorption(raw.data(), kRes, kLo, kHi, 1);
    for (const auto& [a, b] : random_segments(5, 13, 0.9)) {
      for (int ch = 0; ch < 3; ++ch) {
        check_forward_vs_reverse(raw, 1, [&](auto& reader) {
          using R = std::decay_t<decltype(reader.read(0, 0))>;
          const R w = reader.read(1, 0) * 0.05;  // the ends move with parameter 0
          return scene::transmittance(reader, f, Vec3<R>(R(a.x) + w, R(a.y), R(a.z)),
                                      Vec3<R>(R(b.x), R(b.y) - w, R(b.z)), AbsorptionIntegration{samples, 0.5f})[ch];
        });
      }
    }
  }
}

TEST_CASE("frozen parameters cost no leaves") {
  const std::vector<float> raw = to_float(uniform_values(std::size_t(kRes.x * kRes.y * kRes.z * 3), -1.0, 2.0, 3));
  const AbsorptionField f = scene::grid_absorption(raw.data(), kRes, kLo, kHi);  // buffer -1
  ad::ParamSet set;
  ad::Tape<float> tape(1 << 12);
  ad::LeafRecord log[4];
  ad::ParamReader<ad::Var<float>> rev(&set, &tape, log, 4);
  const auto a = Vec3<ad::Var<float>>(tape.variable(-0.3f), 0.1f, 0.2f);
  const auto T = scene::transmittance(rev, f, a, Vec3<ad::Var<float>>(0.5f, -0.2f, -0.1f));
  CHECK(rev.size() == 0);
  tape.backward(T.x);
  CHECK(tape.adjoint(a.x) != 0.0f);  // still differentiable with respect to the ends
}

// AbsorptionField::softplus_table: a float pass reads sigma from the table
// instead of evaluating softplus; the values, tangents and gradients must be
// the same bits, and a pass in double must not read the float table.
TEST_CASE("the softplus table changes no bit of a float pass") {
  // raw values across softplus's branches: far negative, near 0, far positive
  std::vector<float> raw = to_float(uniform_values(std::size_t(kRes.x * kRes.y * kRes.z * 3), -25.0, 25.0, 91));
  raw[0] = 0.0f;
  raw[1] = -1e-7f;
  raw[2] = 40.0f;
  std::vector<float> table(2 * raw.size());
  scene::fill_softplus_table(raw.data(), raw.size(), table.data());
  const auto bits = [](float x) {
    std::uint32_t u;
    std::memcpy(&u, &x, sizeof u);
    return u;
  };
  for (const bool homogeneous : {false, true}) {
    const AbsorptionField plain_field =
        homogeneous ? scene::homogeneous_absorption(raw.data(), 1) : scene::grid_absorption(raw.data(), kRes, kLo, kHi, 1);
    AbsorptionField table_field = plain_field;
    table_field.softplus_table = table.data();
    for (int samples : {0, 4}) {
      CAPTURE(homogeneous);
      CAPTURE(samples);
      const AbsorptionIntegration q{samples, 0.37f};
      for (const auto& [a, b] : random_segments(40, 17, 0.8)) {
        ad::ParamSet set;
        set.buffers[1].values = raw.data();
        set.buffers[1].size = std::int32_t(raw.size());
        // float
        ad::ParamReader<float> plain(&set);
        const Vec3f d0 = depth<float>(plain, plain_field, a, b, q), d1 = depth<float>(plain, table_field, a, b, q);
        // forward mode along two tangents
        std::vector<float> t0 = to_float(uniform_values(raw.size(), -1.0, 1.0, 5)),
                           t1 = to_float(uniform_values(raw.size(), -1.0, 1.0, 6));
        set.buffers[1].tangents[0] = t0.data();
        set.buffers[1].tangents[1] = t1.data();
        ad::ParamReader<ad::Dual<float, 2>> fwd(&set);
        const Vec3<ad::Dual<float, 2>> f0 = depth<ad::Dual<float, 2>>(fwd, plain_field, a, b, q),
                                        f1 = depth<ad::Dual<float, 2>>(fwd, table_field, a, b, q);
        // reverse mode: the gradient of the three channels' sum
        std::vector<float> g[2];
        float v[2];
        for (int k = 0; k < 2; ++k) {
          g[k].assign(raw.size(), 0.0f);
          set.buffers[1].gradient = g[k].data();
          ad::Tape<float> tape(1 << 14);
          std::vector<ad::LeafRecord> log(1 << 12);
          ad::ParamReader<ad::Var<float>> rev(&set, &tape, log.data(), std::int32_t(log.size()));
          const Vec3<ad::Var<float>> d = depth<ad::Var<float>>(rev, k ? table_field : plain_field, a, b, q);
          const ad::Var<float> y = d.x + d.y + d.z;
          REQUIRE_FALSE(tape.overflowed());
          tape.backward(y);
          rev.scatter();
          v[k] = y.value;
        }
        for (int ch = 0; ch < 3; ++ch) {
          CHECK(bits(d0[ch]) == bits(d1[ch]));
          CHECK(bits(f0[ch].value) == bits(f1[ch].value));
          CHECK(bits(f0[ch].grad[0]) == bits(f1[ch].grad[0]));
          CHECK(bits(f0[ch].grad[1]) == bits(f1[ch].grad[1]));
        }
        CHECK(bits(v[0]) == bits(v[1]));
        std::size_t differing = 0;
        for (std::size_t i = 0; i < raw.size(); ++i) differing += bits(g[0][i]) != bits(g[1][i]);
        CHECK(differing == 0);
        // a double pass evaluates softplus itself: a stale table (all zeros) changes nothing there
        std::vector<float> zeros(table.size(), 0.0f);
        AbsorptionField stale = plain_field;
        stale.softplus_table = zeros.data();
        ad::ParamReader<double> plain_d(&set);
        const Vec3d e0 = depth<double>(plain_d, plain_field, a, b, q), e1 = depth<double>(plain_d, stale, a, b, q);
        CHECK(e0 == e1);
      }
    }
  }
}
