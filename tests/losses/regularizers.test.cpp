// Geometry regularizers: closed forms on tiny inputs, the eigenvalue solver
// against Eigen, gradients against central differences, Dual against Var,
// finite gradients at degenerate inputs, and (skipped by default) their cost.
#include "difftrans/losses/flexicubes_terms.hpp"
#include "difftrans/losses/mesh_terms.hpp"

#include <doctest/doctest.h>

#include <Eigen/Dense>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "support/ad_check.hpp"
#include "support/flexicubes_grid.hpp"
#include "support/shapes.hpp"

namespace {

using namespace difftrans;
using namespace difftrans::geometry;
using namespace difftrans::losses;

// ------------------------------------------------------------------ meshes

struct Mesh {
  std::vector<Vec3d> p;
  std::vector<std::int32_t> t;
};

// A (nu × nv)-cell grid of quads, each cut into (a b c) (a c d), positions
// pos(u, v) for integer u, v; wrap_u / wrap_v glue the last column / row to
// the first (cylinders, tori).
Mesh grid_mesh(int nu, int nv, bool wrap_u, bool wrap_v, const std::function<Vec3d(double, double)>& pos) {
  Mesh m;
  const int NU = wrap_u ? nu : nu + 1, NV = wrap_v ? nv : nv + 1;
  for (int j = 0; j < NV; ++j)
    for (int i = 0; i < NU; ++i) m.p.push_back(pos(double(i), double(j)));
  auto id = [&](int i, int j) { return std::int32_t((i % NU) + NU * (j % NV)); };
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const std::int32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      m.t.insert(m.t.end(), {a, b, c, a, c, d});
    }
  return m;
}

Mesh flat_grid(int n) {
  return grid_mesh(n, n, false, false, [](double u, double v) { return Vec3d(u, v, 0.0); });
}

Mesh cylinder(int around, int along, double radius, double height) {
  return grid_mesh(around, along, true, false, [=](double u, double v) {
    const double a = 2.0 * pi_v<double> * u / around;
    return Vec3d(radius * std::cos(a), radius * std::sin(a), height * v / along);
  });
}

Mesh torus(int around, int tube, double big, double small) {
  return grid_mesh(around, tube, true, true, [=](double u, double v) {
    const double a = 2.0 * pi_v<double> * u / around, b = 2.0 * pi_v<double> * v / tube;
    const double r = big + small * std::cos(b);
    return Vec3d(r * std::cos(a), r * std::sin(a), small * std::sin(b));
  });
}

Mesh icosphere(double radius, int levels) {
  const dt_test::Shape s = dt_test::make_icosphere(float(radius), levels);
  Mesh m;
  for (std::size_t i = 0; i < s.positions.size(); i += 3)
    m.p.push_back(Vec3d(s.positions[i], s.positions[i + 1], s.positions[i + 2]));
  m.t = s.triangles;
  return m;
}

// Regular tetrahedron with outward counter-clockwise faces.
Mesh tetrahedron() {
  Mesh m;
  m.p = {Vec3d(1, 1, 1), Vec3d(1, -1, -1), Vec3d(-1, 1, -1), Vec3d(-1, -1, 1)};
  m.t = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2};
  for (std::size_t f = 0; f < 4; ++f) {  // make every face point away from the centre
    const Vec3d a = m.p[std::size_t(m.t[3 * f])], b = m.p[std::size_t(m.t[3 * f + 1])], c = m.p[std::size_t(m.t[3 * f + 2])];
    if (glm::dot(glm::cross(b - a, c - a), a + b + c) < 0.0) std::swap(m.t[3 * f + 1], m.t[3 * f + 2]);
  }
  return m;
}

void jitter(Mesh& m, double amount, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  for (Vec3d& x : m.p) x += Vec3d(u(rng), u(rng), u(rng));
}

// The positions as constants of S.
template <class S>
std::vector<Vec3<S>> as(const std::vector<Vec3d>& p) {
  std::vector<Vec3<S>> v;
  for (const Vec3d& x : p) v.push_back(Vec3<S>(S(x.x), S(x.y), S(x.z)));
  return v;
}

// ------------------------------------------------------------------ derivatives

// Value and gradient (3 per vertex) of f(vertices) in reverse mode.
template <class T, class F>
double reverse_gradient(const std::vector<Vec3d>& p, F&& f, std::vector<double>& grad, int* nodes = nullptr,
                        std::int32_t capacity = 1 << 22) {
  using V = ad::Var<T>;
  ad::Tape<T> tape(capacity);
  std::vector<Vec3<V>> v;
  for (const Vec3d& x : p) v.push_back(Vec3<V>(tape.variable(T(x.x)), tape.variable(T(x.y)), tape.variable(T(x.z))));
  const V y = f(v);
  REQUIRE_FALSE(tape.overflowed());
  if (nodes) *nodes = tape.size();
  tape.backward(y);
  grad.assign(3 * p.size(), 0.0);
  for (std::size_t i = 0; i < p.size(); ++i)
    for (int a = 0; a < 3; ++a) grad[3 * i + std::size_t(a)] = double(tape.adjoint(v[i][a]));
  return double(y.value);
}

// Directional derivative along dir (3 per vertex) in forward mode.
template <class T, class F>
double forward_directional(const std::vector<Vec3d>& p, const std::vector<double>& dir, F&& f) {
  using D = ad::Dual<T, 1>;
  std::vector<Vec3<D>> v(p.size());
  for (std::size_t i = 0; i < p.size(); ++i)
    for (int a = 0; a < 3; ++a) {
      D x(T(p[i][a]));
      x.grad[0] = T(dir[3 * i + std::size_t(a)]);
      v[i][a] = x;
    }
  return double(f(v).grad[0]);
}

// Central differences of f in double, every coordinate, against `grad`.
template <class F>
void check_against_central_differences(const std::vector<Vec3d>& p0, F&& f, const std::vector<double>& grad,
                                       double tolerance) {
  std::vector<Vec3d> p = p0;
  int nonzero = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (int a = 0; a < 3; ++a) {
      const double h = 1e-6;
      p[i][a] = p0[i][a] + h;
      const double fp = double(f(p));
      p[i][a] = p0[i][a] - h;
      const double fm = double(f(p));
      p[i][a] = p0[i][a];
      const double fd = (fp - fm) / (2.0 * h);
      CAPTURE(i);
      CAPTURE(a);
      CHECK(grad[3 * i + std::size_t(a)] == doctest::Approx(fd).epsilon(tolerance).scale(1.0));
      nonzero += std::abs(fd) > 1e-8;
    }
  CHECK(nonzero > int(p.size()));  // the term does depend on the positions
}

bool all_finite_values(const std::vector<double>& g) {
  for (double x : g)
    if (!std::isfinite(x)) return false;
  return true;
}

// ------------------------------------------------------------------ grids

using dt_test::GridData;


// Every grid term, as one function of the unknowns (the scalar S, a reader).
enum class GridTerm { dilation, bce, weight_l1, dev };

template <class S, class Reader>
S grid_term(GridTerm term, const GridData& g, Reader& reader) {
  const FlexiCubesInputs in = g.inputs(true);
  switch (term) {
    case GridTerm::dilation: return sdf_dilation_loss<S>(g.grid, in.sdf, reader);
    case GridTerm::bce: return sdf_sign_change_bce_loss<S>(g.grid, in.sdf, reader);
    case GridTerm::weight_l1: return flexicubes_weight_l1<S>(in, reader);
    case GridTerm::dev: {
      const FlexiCubesMesh<S> mesh = flexicubes_extract<S>(g.grid, in, reader);
      return flexicubes_dev_loss<S>(g.grid, in, reader, mesh);
    }
  }
  return S(0);
}

// Plain double value of a grid term (every source read as a constant).
double grid_term_value(GridTerm term, const GridData& g) {
  ad::ParamSet set;
  for (int b = 0; b < 5; ++b) {
    set.buffers[b].values = g.buffer(b)->data();
    set.buffers[b].size = std::int32_t(g.buffer(b)->size());
  }
  ad::ParamReader<double> reader(&set);
  return grid_term<double>(term, g, reader);
}

struct GridGradients {
  std::vector<float> buffer[5];
  double value = 0.0;
};

template <class T>
GridGradients grid_term_gradient(GridTerm term, GridData& g) {
  GridGradients out;
  ad::ParamSet set;
  for (int b = 0; b < 5; ++b) {
    out.buffer[b].assign(g.buffer(b)->size(), 0.0f);
    set.buffers[b].values = g.buffer(b)->data();
    set.buffers[b].size = std::int32_t(g.buffer(b)->size());
    set.buffers[b].gradient = out.buffer[b].data();
  }
  ad::Tape<T> tape(1 << 21);
  std::vector<ad::LeafRecord> log(1 << 17);
  ad::ParamReader<ad::Var<T>> reader(&set, &tape, log.data(), std::int32_t(log.size()));
  const ad::Var<T> y = grid_term<ad::Var<T>>(term, g, reader);
  REQUIRE_FALSE(tape.overflowed());
  REQUIRE_FALSE(reader.overflowed());
  tape.backward(y);
  reader.scatter();
  out.value = double(y.value);
  return out;
}

// A small grid around a sphere whose unknowns are all random (away from sign flips).
GridData gradient_grid(std::uint32_t seed) {
  std::mt19937 rng(seed);
  GridData g(4);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  g.fill([&](Vec3f p) {
    float s = glm::length(p) - 0.62f + 0.1f * u(rng);
    if (std::abs(s) < 0.03f) s = s < 0.0f ? -0.03f : 0.03f;
    return s;
  });
  g.randomize_unknowns(rng, 1.0f, 1.0f);
  return g;
}

double bce_reference(double x, double t) {  // the textbook form, fine for moderate x
  const double s = 1.0 / (1.0 + std::exp(-x));
  return -t * std::log(s) - (1.0 - t) * std::log(1.0 - s);
}

}  // namespace

// ================================================================= small pieces

TEST_CASE_TEMPLATE("regularizers: BCE with logits by hand, stable for large logits", S, DT_ALL_SCALARS) {
  const double tl = dt_test::tol<S>();
  for (double x : {-4.0, -0.5, 0.0, 0.3, 2.5})
    for (double t : {0.0, 1.0}) {
      CAPTURE(x);
      CHECK(double(value_of(bce_with_logits(S(x), t))) == doctest::Approx(bce_reference(x, t)).epsilon(tl));
    }
  CHECK(double(value_of(bce_with_logits(S(0.0), 1.0))) == doctest::Approx(std::log(2.0)).epsilon(tl));
  // far out: BCE(x, 0) → x, BCE(−x, 1) → x, BCE(x, 1) → e^−x; no overflow
  CHECK(double(value_of(bce_with_logits(S(200.0), 0.0))) == doctest::Approx(200.0).epsilon(tl));
  CHECK(double(value_of(bce_with_logits(S(-200.0), 1.0))) == doctest::Approx(200.0).epsilon(tl));
  CHECK(double(value_of(bce_with_logits(S(200.0), 1.0))) >= 0.0);
  CHECK(double(value_of(bce_with_logits(S(200.0), 1.0))) < 1e-30);
}

TEST_CASE_TEMPLATE("regularizers: d BCE / dx = sigmoid(x) - t, also at 0", S, DT_AD_SCALARS) {
  for (double x : {-3.0, -0.2, 0.0, 0.7, 40.0})
    for (double t : {0.0, 1.0}) {
      const double d = dt_test::derivative<S>([&](const S& v) { return bce_with_logits(v, t); }, x);
      CAPTURE(x);
      CHECK(d == doctest::Approx(1.0 / (1.0 + std::exp(-x)) - t).epsilon(dt_test::tol<S>()).scale(1.0));
    }
}

TEST_CASE_TEMPLATE("regularizers: triangle and mean face area", S, DT_ALL_SCALARS) {
  // the unit square split in two: two triangles of area 1/2
  const std::vector<Vec3d> p = {Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(1, 1, 0), Vec3d(0, 1, 0)};
  const std::vector<std::int32_t> t = {0, 1, 2, 0, 2, 3};
  CHECK(double(value_of(mean_face_area(as<S>(p), t))) == doctest::Approx(0.5).epsilon(dt_test::tol<S>()));
  // a right triangle with legs 2 and 3, tilted out of the plane: area 3
  const Vec3d u = glm::normalize(Vec3d(1, 2, 2)), w = glm::normalize(glm::cross(u, Vec3d(0, 0, 1)));
  const Vec3d o(0.3, -0.2, 0.7);
  const auto q = as<S>({o, o + 2.0 * u, o + 3.0 * w});
  CHECK(double(value_of(triangle_area(q[0], q[1], q[2]))) == doctest::Approx(3.0).epsilon(dt_test::tol<S>()));
  // a 3 × 3 grid of unit quads: 18 triangles of area 1/2
  const Mesh g = flat_grid(3);
  CHECK(double(value_of(mean_face_area(as<S>(g.p), g.t))) == doctest::Approx(0.5).epsilon(dt_test::tol<S>()));
  CHECK(double(value_of(mean_face_area(std::vector<Vec3<S>>{}, std::vector<std::int32_t>{}))) == 0.0);
}

TEST_CASE("regularizers: smallest eigenvalue (Jacobi + Rayleigh, and closed form) agrees with Eigen") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double worst = 0.0, worst_closed = 0.0;
  for (int n = 0; n < 2000; ++n) {
    Eigen::Matrix3d m;
    for (int i = 0; i < 3; ++i)
      for (int j = i; j < 3; ++j) m(i, j) = m(j, i) = u(rng) * (n % 3 == 0 ? 100.0 : 1.0);
    if (n % 5 == 0) m = m * m.transpose() * 1e-3;  // positive semi-definite, small
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m);
    const double ref = eig.eigenvalues()(0), scale = m.norm();
    const double got = smallest_eigenvalue_sym3(m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2));
    const double closed = smallest_eigenvalue_sym3_closed_form(m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2));
    const double f = smallest_eigenvalue_sym3(float(m(0, 0)), float(m(1, 1)), float(m(2, 2)), float(m(0, 1)),
                                              float(m(0, 2)), float(m(1, 2)));
    const double fc = smallest_eigenvalue_sym3_closed_form(float(m(0, 0)), float(m(1, 1)), float(m(2, 2)),
                                                           float(m(0, 1)), float(m(0, 2)), float(m(1, 2)));
    worst = std::max(worst, std::abs(got - ref) / scale);
    worst_closed = std::max(worst_closed, std::abs(closed - ref) / scale);
    CHECK(std::abs(got - ref) <= 1e-14 * scale);
    CHECK(std::abs(closed - ref) <= 1e-11 * scale);
    CHECK(std::abs(f - ref) <= 1e-6 * scale);
    CHECK(std::abs(fc - ref) <= 1e-4 * scale);
    // the eigenvector: unit, and A v = λ v
    const double mm[6] = {m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2)};
    double v[3];
    const double lambda = smallest_eigenvector_sym3(mm, v);
    const Eigen::Vector3d ev(v[0], v[1], v[2]);
    CHECK(std::abs(ev.norm() - 1.0) < 1e-14);
    CHECK((m * ev - lambda * ev).norm() <= 1e-14 * scale);
  }
  MESSAGE("worst relative error: Jacobi + Rayleigh " << worst << ", closed form " << worst_closed);
}

TEST_CASE_TEMPLATE("regularizers: smallest eigenvalue at repeated eigenvalues, with finite derivatives", S,
                   DT_AD_SCALARS) {
  // A = R diag(l) Rᵀ with a fixed rotation R, the entries moved along one
  // direction E so that each case is one-dimensional: A(x) = A + x E.
  const bool is_float = std::is_same_v<ad::scalar_t<S>, float>;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Matrix3d E = (Eigen::Matrix3d() << 0.3, 0.1, -0.2, 0.1, -0.5, 0.4, -0.2, 0.4, 0.2).finished();
  const double cases[][3] = {{1, 1, 1}, {0, 0, 2}, {0, 2, 2}, {0.5, 3, 3}, {0, 0, 0}, {1, 2, 4}};
  for (int closed = 0; closed < 2; ++closed)
    for (const auto& l : cases) {
      const Eigen::Matrix3d A = R * Eigen::Vector3d(l[0], l[1], l[2]).asDiagonal() * R.transpose();
      auto f = [&](const S& x) {
        auto e = [&](int i, int j) { return S(A(i, j) + x * E(i, j)); };
        return closed ? smallest_eigenvalue_sym3_closed_form(e(0, 0), e(1, 1), e(2, 2), e(0, 1), e(0, 2), e(1, 2))
                      : smallest_eigenvalue_sym3(e(0, 0), e(1, 1), e(2, 2), e(0, 1), e(0, 2), e(1, 2));
      };
      double value = 0.0;
      const double d = dt_test::derivative<S>(f, 0.0, &value);
      CAPTURE(closed);
      CAPTURE(l[0]);
      CAPTURE(l[1]);
      CAPTURE(l[2]);
      // the closed form loses half the digits at a double smallest eigenvalue
      const double value_tol = closed ? (is_float ? 2e-3 : 1e-7) : (is_float ? 1e-6 : 1e-14);
      CHECK(value == doctest::Approx(l[0]).epsilon(value_tol).scale(1.0));
      CHECK(std::isfinite(d));
      // any subgradient lies between the one-sided derivatives (from Eigen);
      // where the smallest eigenvalue is simple both equal vᵀ E v
      const double h = 1e-6;
      auto lmin = [&](double x) { return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(A + x * E).eigenvalues()(0); };
      const double right = (lmin(h) - lmin(0.0)) / h, left = (lmin(0.0) - lmin(-h)) / h;
      const double slack = is_float ? 1e-3 : 1e-5;
      CHECK(d >= std::min(left, right) - slack);
      CHECK(d <= std::max(left, right) + slack);
      if (l[0] < l[1]) {
        const Eigen::Vector3d v = R.col(0);
        CHECK(d == doctest::Approx(v.dot(E * v)).epsilon(is_float ? 1e-3 : 1e-7));
      }
    }
}

// ================================================================= grid terms

TEST_CASE_TEMPLATE("regularizers: SDF dilation and weight L1 by hand", S, float, double, ad::Dual<double, 1>) {
  GridData g(1);
  g.sdf = {-0.5f, 1.0f, 2.0f, 0.25f, -1.0f, 3.0f, 0.5f, 1.5f};
  ad::ParamSet set;
  ad::ParamReader<S> reader(&set);  // every source is constant here (buffer < 0)
  const FlexiCubesInputs in = g.inputs(false);
  CHECK(double(value_of(sdf_dilation_loss<S>(g.grid, in.sdf, reader))) == doctest::Approx(6.75 / 8.0));
  // no weights at all: 0
  CHECK(double(value_of(flexicubes_weight_l1<S>(in, reader))) == 0.0);
  g.alpha = {0.5f, -0.5f, 0.0f, 1.0f, -2.0f, 0.0f, 0.0f, 0.0f};
  g.gamma = {-3.0f};
  // (0.5 + 0.5 + 1 + 2 + 3) / 9 entries
  CHECK(double(value_of(flexicubes_weight_l1<S>(g.inputs(false), reader))) == doctest::Approx(7.0 / 9.0));
}

TEST_CASE_TEMPLATE("regularizers: sign-change BCE on one cube by hand", S, float, double, ad::Dual<double, 1>) {
  GridData g(1);
  ad::ParamSet set;
  ad::ParamReader<S> reader(&set);
  // all outside: no changing edge, 0
  CHECK(double(value_of(sdf_sign_change_bce_loss<S>(g.grid, g.inputs().sdf, reader))) == 0.0);
  // corner 0 inside (−0.5), the rest +1: edges 0-1, 0-2, 0-4 change sign, each
  // BCE(−0.5, 1) + BCE(1, 0) = log(1 + e^0.5) + log(1 + e)
  g.sdf[0] = -0.5f;
  const double expected = std::log(1.0 + std::exp(0.5)) + std::log(1.0 + std::exp(1.0));
  CHECK(double(value_of(sdf_sign_change_bce_loss<S>(g.grid, g.inputs().sdf, reader))) ==
        doctest::Approx(expected).epsilon(dt_test::tol<S>()));
  // corners 0 and 7 inside (−0.5, −2), 3 + 3 changing edges
  g.sdf[7] = -2.0f;
  const double e7 = std::log(1.0 + std::exp(2.0)) + std::log(1.0 + std::exp(1.0));  // BCE(−2, 1) + BCE(1, 0)
  CHECK(double(value_of(sdf_sign_change_bce_loss<S>(g.grid, g.inputs().sdf, reader))) ==
        doctest::Approx((3.0 * expected + 3.0 * e7) / 6.0).epsilon(dt_test::tol<S>()));
}

TEST_CASE("regularizers: L_dev on one cube by hand") {
  // unit cube, corner 0 inside: crossings at t = s_a / (s_a − s_b) on edges
  // 0-1, 0-2, 0-4; without weights the dual vertex is their mean
  GridData g(1, Vec3f(0.0f), Vec3f(1.0f));
  g.sdf = {-1.0f, 1.0f, 3.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f};
  const Vec3d u[3] = {Vec3d(0.5, 0, 0), Vec3d(0, 0.25, 0), Vec3d(0, 0, 0.5)};
  const Vec3d v = (u[0] + u[1] + u[2]) / 3.0;
  double d[3], mean = 0.0;
  for (int k = 0; k < 3; ++k) mean += (d[k] = glm::length(u[k] - v)) / 3.0;
  const double expected = (std::abs(d[0] - mean) + std::abs(d[1] - mean) + std::abs(d[2] - mean)) / 3.0;
  CHECK(expected > 0.01);
  CHECK(grid_term_value(GridTerm::dev, g) == doctest::Approx(expected).epsilon(1e-6));
  // symmetric crossings: all distances equal, 0
  g.sdf[2] = 1.0f;
  CHECK(grid_term_value(GridTerm::dev, g) == doctest::Approx(0.0).scale(1.0).epsilon(1e-7));
  // a β weight pulls the dual vertex towards one crossing: positive again
  g.beta.assign(12, 0.0f);
  g.beta[0] = 1.5f;
  CHECK(grid_term_value(GridTerm::dev, g) > 0.01);
}

TEST_CASE("regularizers: L_dev is 0 for a flat SDF plane, positive for a sphere") {
  // a plane z = c crosses only z-edges, all at the same height: every dual
  // vertex is equidistant from the crossings of its group (no deformation, α = β = 1)
  GridData plane(6);
  plane.fill([](Vec3f p) { return p.z - 0.1f; });
  CHECK(grid_term_value(GridTerm::dev, plane) == doctest::Approx(0.0).scale(1.0).epsilon(1e-7));
  GridData sphere(8);
  sphere.fill([](Vec3f p) { return glm::length(p) - 0.6f; });
  CHECK(grid_term_value(GridTerm::dev, sphere) > 1e-4);
}

TEST_CASE("regularizers: grid terms' gradients match central differences") {
  GridData g = gradient_grid(41);
  const char* names[4] = {"dilation", "bce", "weight_l1", "dev"};
  const char* buffers[5] = {"sdf", "deform", "alpha", "beta", "gamma"};
  for (GridTerm term : {GridTerm::dilation, GridTerm::bce, GridTerm::weight_l1, GridTerm::dev}) {
    CAPTURE(names[int(term)]);
    const GridGradients grad = grid_term_gradient<double>(term, g);
    CHECK(grad.value == doctest::Approx(grid_term_value(term, g)).epsilon(1e-12));
    int nonzero = 0;
    for (int b = 0; b < 5; ++b) {
      std::vector<float>& values = *g.buffer(b);
      // every sdf entry, a sample of the others (the test must stay quick)
      const std::size_t stride = b == 0 ? 1 : 7;
      for (std::size_t i = 0; i < values.size(); i += stride) {
        float& x = values[i];
        const float x0 = x;
        auto central = [&](float h) {
          const float xp = x0 + h, xm = x0 - h;
          x = xp;
          const double fp = grid_term_value(term, g);
          x = xm;
          const double fm = grid_term_value(term, g);
          x = x0;
          return (fp - fm) / (double(xp) - double(xm));
        };
        const double fd = (4.0 * central(2.5e-4f) - central(5e-4f)) / 3.0;  // Richardson
        CAPTURE(buffers[b]);
        CAPTURE(i);
        CHECK(double(grad.buffer[b][i]) == doctest::Approx(fd).epsilon(1e-4).scale(1.0));
        nonzero += std::abs(fd) > 1e-9;
      }
    }
    CHECK(nonzero > 10);
  }
}

TEST_CASE("regularizers: grid terms, forward mode (Dual) agrees with reverse mode (Var)") {
  GridData g = gradient_grid(43);
  std::mt19937 rng(47);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> dir[5];
  ad::ParamSet set;
  for (int b = 0; b < 5; ++b) {
    dir[b].resize(g.buffer(b)->size());
    for (float& x : dir[b]) x = u(rng);
    set.buffers[b].values = g.buffer(b)->data();
    set.buffers[b].size = std::int32_t(g.buffer(b)->size());
    set.buffers[b].tangents[0] = dir[b].data();
  }
  for (GridTerm term : {GridTerm::dilation, GridTerm::bce, GridTerm::weight_l1, GridTerm::dev}) {
    CAPTURE(int(term));
    const GridGradients rev = grid_term_gradient<double>(term, g);
    const GridGradients rev_f = grid_term_gradient<float>(term, g);
    double expected = 0.0, expected_f = 0.0;
    for (int b = 0; b < 5; ++b)
      for (std::size_t i = 0; i < dir[b].size(); ++i) {
        expected += double(dir[b][i]) * double(rev.buffer[b][i]);
        expected_f += double(dir[b][i]) * double(rev_f.buffer[b][i]);
      }
    ad::ParamReader<ad::Dual<double, 1>> reader(&set);
    const auto y = grid_term<ad::Dual<double, 1>>(term, g, reader);
    CHECK(y.value == doctest::Approx(rev.value).epsilon(1e-12));
    CHECK(y.grad[0] == doctest::Approx(expected).epsilon(1e-6));
    CHECK(expected_f == doctest::Approx(expected).epsilon(1e-3));
    ad::ParamReader<ad::Dual<float, 1>> reader_f(&set);
    CHECK(double(grid_term<ad::Dual<float, 1>>(term, g, reader_f).grad[0]) == doctest::Approx(expected).epsilon(1e-3));
  }
}

TEST_CASE("regularizers: the tape-free dilation and weight L1 match the reader versions") {
  GridData g = gradient_grid(53);
  g.alpha[3] = 0.0f;  // an exact 0: subgradient 0
  for (GridTerm term : {GridTerm::dilation, GridTerm::weight_l1}) {
    CAPTURE(int(term));
    const GridGradients ref = grid_term_gradient<double>(term, g);
    std::vector<float> grads[5];
    ad::ParamSet set;
    for (int b = 0; b < 5; ++b) {
      grads[b].assign(g.buffer(b)->size(), 0.5f);  // adds to what is there
      set.buffers[b].values = g.buffer(b)->data();
      set.buffers[b].size = std::int32_t(g.buffer(b)->size());
      set.buffers[b].gradient = grads[b].data();
    }
    const FlexiCubesInputs in = g.inputs(true);
    const double w = 2.5;
    const double value = term == GridTerm::dilation ? sdf_dilation_backward(g.grid, in.sdf, set, w)
                                                    : flexicubes_weight_l1_backward(in, set, w);
    CHECK(value == doctest::Approx(ref.value).epsilon(1e-12));
    for (int b = 0; b < 5; ++b)
      for (std::size_t i = 0; i < grads[b].size(); ++i) {
        CAPTURE(b);
        CAPTURE(i);
        CHECK(double(grads[b][i]) == doctest::Approx(0.5 + w * double(ref.buffer[b][i])).epsilon(1e-6));
      }
  }
}

// ================================================================= mesh terms

TEST_CASE("regularizers: mesh adjacency of a tetrahedron and of an open square") {
  const Mesh t = tetrahedron();
  const MeshAdjacency a = mesh_adjacency(t.t, 4);
  CHECK(a.num_edges() == 6);
  for (std::int32_t e = 0; e < 6; ++e) CHECK(a.edge_faces[std::size_t(2 * e + 1)] >= 0);
  for (std::int32_t v = 0; v < 4; ++v) {
    CHECK(a.boundary[std::size_t(v)] == 0);
    CHECK(a.vv_offsets[std::size_t(v) + 1] - a.vv_offsets[std::size_t(v)] == 3);
    CHECK(a.vf_offsets[std::size_t(v) + 1] - a.vf_offsets[std::size_t(v)] == 3);
  }
  for (std::size_t k = 0; k < a.vf_faces.size(); ++k)  // the corner points back at the vertex
    CHECK(t.t[std::size_t(3 * a.vf_faces[k] + a.vf_corner[k])] >= 0);
  const MeshAdjacency s = mesh_adjacency({0, 1, 2, 0, 2, 3}, 4);
  CHECK(s.num_edges() == 5);
  int interior = 0;
  for (std::int32_t e = 0; e < 5; ++e) interior += s.edge_faces[std::size_t(2 * e + 1)] >= 0;
  CHECK(interior == 1);
  for (std::int32_t v = 0; v < 4; ++v) CHECK(s.boundary[std::size_t(v)] == 1);
}

TEST_CASE_TEMPLATE("regularizers: developability is 0 on flat and cylindrical patches, positive on a sphere", S,
                   float, double, ad::Dual<double, 1>, ad::Var<float>) {
  const bool is_float = std::is_same_v<ad::scalar_t<S>, float>;
  const double zero = is_float ? 2e-6 : 1e-13;
  // a flat grid, rotated out of the xy plane and jittered within its plane
  Mesh flat = flat_grid(5);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, -1, 2).normalized()).toRotationMatrix();
  for (Vec3d& p : flat.p) {
    const Eigen::Vector3d q = R * Eigen::Vector3d(p.x + u(rng), p.y + u(rng), 0.0);
    p = Vec3d(q.x(), q.y(), q.z());
  }
  const MeshAdjacency af = mesh_adjacency(flat.t, std::int32_t(flat.p.size()));
  CHECK(std::abs(double(value_of(developability_loss(as<S>(flat.p), flat.t, af)))) < zero);
  // an open cylinder: every interior vertex's normals lie on a great circle
  const Mesh cyl = cylinder(12, 5, 0.8, 2.0);
  const MeshAdjacency ac = mesh_adjacency(cyl.t, std::int32_t(cyl.p.size()));
  CHECK(std::abs(double(value_of(developability_loss(as<S>(cyl.p), cyl.t, ac)))) < zero);
  // with boundary vertices too: still developable
  CHECK(std::abs(double(value_of(developability_loss(as<S>(cyl.p), cyl.t, ac, Reduction::sum, false)))) < 50 * zero);
  // a sphere: clearly positive at every vertex
  const Mesh sph = icosphere(1.0, 2);
  const MeshAdjacency as_ = mesh_adjacency(sph.t, std::int32_t(sph.p.size()));
  const double mean = double(value_of(developability_loss(as<S>(sph.p), sph.t, as_)));
  const double sum = double(value_of(developability_loss(as<S>(sph.p), sph.t, as_, Reduction::sum)));
  CHECK(mean > 1e-3);
  CHECK(sum == doctest::Approx(mean * double(sph.p.size())).epsilon(1e-4));
  // a finer sphere is flatter around each vertex
  const Mesh fine = icosphere(1.0, 3);
  const MeshAdjacency afine = mesh_adjacency(fine.t, std::int32_t(fine.p.size()));
  CHECK(double(value_of(developability_loss(as<S>(fine.p), fine.t, afine))) < 0.5 * mean);
}

TEST_CASE("regularizers: developability of a regular cone apex in closed form") {
  // apex at the origin, n rim vertices at (cos, sin, -h): the apex's faces all
  // have the same angle θ and normals on a circle of polar angle β, so
  // A = nθ diag(sin²β / 2, sin²β / 2, cos²β) and λ_min = min(nθ sin²β / 2, nθ cos²β).
  const int n = 7;
  const double h = 0.6;
  Mesh m;
  m.p.push_back(Vec3d(0.0));
  for (int k = 0; k < n; ++k) {
    const double a = 2.0 * pi_v<double> * k / n;
    m.p.push_back(Vec3d(std::cos(a), std::sin(a), -h));
  }
  for (int k = 0; k < n; ++k) m.t.insert(m.t.end(), {0, 1 + k, 1 + (k + 1) % n});
  const MeshAdjacency adj = mesh_adjacency(m.t, std::int32_t(m.p.size()));
  const Vec3d a = m.p[1], b = m.p[2];
  const double theta = std::acos(glm::dot(a, b) / (glm::length(a) * glm::length(b)));
  const Vec3d nrm = glm::normalize(glm::cross(a, b));
  const double cb = nrm.z, sb2 = 1.0 - cb * cb;
  const double expected = std::min(n * theta * sb2 / 2.0, n * theta * cb * cb);
  CHECK(developability_loss(m.p, m.t, adj, Reduction::sum) == doctest::Approx(expected).epsilon(1e-12));
}

TEST_CASE_TEMPLATE("regularizers: edge-normal term 0 on a plane, 32/3 on a regular tetrahedron", S, DT_ALL_SCALARS) {
  const double tl = std::is_same_v<ad::scalar_t<S>, float> ? 1e-5 : 1e-12;
  const Mesh plane = flat_grid(4);
  const MeshAdjacency ap = mesh_adjacency(plane.t, std::int32_t(plane.p.size()));
  CHECK(std::abs(double(value_of(edge_normal_loss(as<S>(plane.p), plane.t, ap)))) < tl);
  // adjacent outward normals of a regular tetrahedron: n_i · n_j = −1/3, six edges of (4/3)²
  const Mesh t = tetrahedron();
  const MeshAdjacency at = mesh_adjacency(t.t, 4);
  CHECK(double(value_of(edge_normal_loss(as<S>(t.p), t.t, at))) == doctest::Approx(32.0 / 3.0).epsilon(tl));
  CHECK(double(value_of(edge_normal_loss(as<S>(t.p), t.t, at, Reduction::mean))) == doctest::Approx(16.0 / 9.0).epsilon(tl));
  // the linear form: six edges of 1 − (−1/3) = 4/3
  CHECK(double(value_of(edge_normal_loss(as<S>(t.p), t.t, at, Reduction::sum, EdgeNormalForm::linear))) ==
        doctest::Approx(8.0).epsilon(tl));
  CHECK(std::abs(double(value_of(edge_normal_loss(as<S>(plane.p), plane.t, ap, Reduction::sum, EdgeNormalForm::linear)))) <
        tl);
}

TEST_CASE("regularizers: the linear edge-normal form pulls a shallow crease harder than the squared one") {
  // two triangles folded by 5° along their shared edge: the squared form's
  // gradient is cubic in the angle, the linear form's linear
  const double theta = 5.0 * 3.14159265358979323846 / 180.0;
  Mesh m;
  m.p = {Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0.5, 1, 0), Vec3d(0.5, -std::cos(theta), std::sin(theta))};
  m.t = {0, 1, 2, 1, 0, 3};
  const MeshAdjacency adj = mesh_adjacency(m.t, 4);
  const double c = std::cos(theta);
  CHECK(edge_normal_loss(m.p, m.t, adj) == doctest::Approx((1 - c) * (1 - c)).epsilon(1e-9));
  CHECK(edge_normal_loss(m.p, m.t, adj, Reduction::sum, EdgeNormalForm::linear) == doctest::Approx(1 - c).epsilon(1e-9));
  const auto pull = [&](EdgeNormalForm form) {
    std::vector<double> grad;
    reverse_gradient<double>(m.p, [&](const auto& v) { return edge_normal_loss(v, m.t, adj, Reduction::sum, form); }, grad);
    return std::abs(grad[3 * 3 + 2]);  // the folded corner's height
  };
  CHECK(pull(EdgeNormalForm::linear) > 100.0 * pull(EdgeNormalForm::squared));
  CHECK(pull(EdgeNormalForm::linear) > 0.05);
}

TEST_CASE_TEMPLATE("regularizers: uniform Laplacian 0 on a regular flat grid's interior, a bump by hand", S,
                   DT_ALL_SCALARS) {
  const double tl = std::is_same_v<ad::scalar_t<S>, float> ? 1e-5 : 1e-12;
  Mesh g = flat_grid(6);  // 7 × 7 vertices, 25 interior, each the centroid of its 6 neighbours
  const MeshAdjacency adj = mesh_adjacency(g.t, std::int32_t(g.p.size()));
  CHECK(std::abs(double(value_of(laplacian_loss(as<S>(g.p), adj)))) < tl);
  CHECK(double(value_of(laplacian_loss(as<S>(g.p), adj, Reduction::mean, false))) > 0.01);  // the border is not
  // lift the centre vertex by b: its own term b², each of its 6 neighbours (b/6)²
  const double b = 0.3;
  g.p[std::size_t(3 + 7 * 3)].z = b;
  CHECK(double(value_of(laplacian_loss(as<S>(g.p), adj))) == doctest::Approx(b * b * (1.0 + 6.0 / 36.0) / 25.0).epsilon(tl));
  CHECK(double(value_of(laplacian_loss(as<S>(g.p), adj, Reduction::sum))) == doctest::Approx(b * b * (1.0 + 6.0 / 36.0)).epsilon(tl));
}

namespace {

// The mesh terms as generic functions of the vertices.
struct MeshTerms {
  const Mesh* mesh;
  const MeshAdjacency* adj;
  int which;
  template <class S>
  S operator()(const std::vector<Vec3<S>>& v) const {
    switch (which) {
      case 0: return mean_face_area(v, mesh->t);
      case 1: return developability_loss(v, mesh->t, *adj);
      case 2: return edge_normal_loss(v, mesh->t, *adj);
      case 3: return edge_normal_loss(v, mesh->t, *adj, Reduction::sum, EdgeNormalForm::linear);
      default: return laplacian_loss(v, *adj);
    }
  }
};
const char* mesh_term_names[5] = {"mean_face_area", "developability", "edge_normal", "edge_normal (linear)", "laplacian"};

}  // namespace

TEST_CASE("regularizers: mesh terms' gradients match central differences (closed and open meshes)") {
  Mesh closed = icosphere(1.0, 1);
  jitter(closed, 0.08, 11);
  Mesh open = flat_grid(4);
  jitter(open, 0.15, 13);
  for (const Mesh* m : {&closed, &open}) {
    const MeshAdjacency adj = mesh_adjacency(m->t, std::int32_t(m->p.size()));
    for (int which = 0; which < 5; ++which) {
      CAPTURE(mesh_term_names[which]);
      const MeshTerms f{m, &adj, which};
      std::vector<double> grad;
      const double value = reverse_gradient<double>(m->p, f, grad);
      CHECK(value == doctest::Approx(f(m->p)).epsilon(1e-14));
      check_against_central_differences(m->p, f, grad, 1e-6);
    }
  }
}

TEST_CASE("regularizers: mesh terms, forward mode (Dual) agrees with reverse mode (Var), float and double") {
  Mesh m = icosphere(1.0, 2);
  jitter(m, 0.03, 17);
  const MeshAdjacency adj = mesh_adjacency(m.t, std::int32_t(m.p.size()));
  std::mt19937 rng(19);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> dir(3 * m.p.size());
  for (double& x : dir) x = u(rng);
  for (int which = 0; which < 5; ++which) {
    CAPTURE(mesh_term_names[which]);
    const MeshTerms f{&m, &adj, which};
    std::vector<double> g, gf;
    reverse_gradient<double>(m.p, f, g);
    reverse_gradient<float>(m.p, f, gf);
    double expected = 0.0, expected_f = 0.0;
    for (std::size_t i = 0; i < dir.size(); ++i) {
      expected += dir[i] * g[i];
      expected_f += dir[i] * gf[i];
    }
    CHECK(forward_directional<double>(m.p, dir, f) == doctest::Approx(expected).epsilon(1e-10));
    CHECK(forward_directional<float>(m.p, dir, f) == doctest::Approx(expected).epsilon(2e-3).scale(1.0));
    CHECK(expected_f == doctest::Approx(expected).epsilon(2e-3).scale(1.0));
  }
}

TEST_CASE("regularizers: finite gradients at degenerate inputs") {
  // a zero-area face (a repeated point) and a collinear face inside a closed mesh
  Mesh m = icosphere(1.0, 1);
  const std::size_t a = std::size_t(m.t[0]), b = std::size_t(m.t[1]), c = std::size_t(m.t[2]);
  m.p[c] = 0.5 * (m.p[a] + m.p[b]);  // face 0 becomes collinear
  const std::size_t f = 17;            // a face away from face 0: two of its corners coincide
  m.p[std::size_t(m.t[3 * f + 1])] = m.p[std::size_t(m.t[3 * f])];
  const MeshAdjacency adj = mesh_adjacency(m.t, std::int32_t(m.p.size()));
  for (int which = 0; which < 5; ++which) {
    CAPTURE(mesh_term_names[which]);
    const MeshTerms f{&m, &adj, which};
    std::vector<double> g, gf;
    CHECK(std::isfinite(reverse_gradient<double>(m.p, f, g)));
    CHECK(all_finite_values(g));
    CHECK(std::isfinite(reverse_gradient<float>(m.p, f, gf)));
    CHECK(all_finite_values(gf));
    std::vector<double> dir(3 * m.p.size(), 1.0);
    CHECK(std::isfinite(forward_directional<double>(m.p, dir, f)));
  }
  // a flat patch: every vertex has a double (zero) smallest eigenvalue
  const Mesh flat = flat_grid(3);
  const MeshAdjacency af = mesh_adjacency(flat.t, std::int32_t(flat.p.size()));
  std::vector<double> g;
  reverse_gradient<double>(flat.p, MeshTerms{&flat, &af, 1}, g);
  CHECK(all_finite_values(g));
  reverse_gradient<float>(flat.p, MeshTerms{&flat, &af, 1}, g);
  CHECK(all_finite_values(g));
  // all points equal: no normals, no angles, a zero matrix
  Mesh point = tetrahedron();
  for (Vec3d& p : point.p) p = Vec3d(0.25, 0.5, 1.0);
  const MeshAdjacency ap = mesh_adjacency(point.t, 4);
  for (int which = 0; which < 5; ++which) {
    reverse_gradient<double>(point.p, MeshTerms{&point, &ap, which}, g);
    CHECK(all_finite_values(g));
  }
}

// ================================================================= cost (run with --no-skip)

namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

TEST_CASE("regularizers: cost on a 64^3 FlexiCubes sphere and a 50k-face mesh" * doctest::skip()) {
  using T = double;
  using V = ad::Var<T>;
  auto now = [] { return std::chrono::steady_clock::now(); };
  {
    GridData g(64);
    std::mt19937 rng(3);
    g.fill([](Vec3f p) { return glm::length(p) - 0.6f; });
    g.randomize_unknowns(rng, 0.2f, 0.2f);
    ad::ParamSet set;
    std::vector<float> grads[5];
    for (int b = 0; b < 5; ++b) {
      grads[b].assign(g.buffer(b)->size(), 0.0f);
      set.buffers[b].values = g.buffer(b)->data();
      set.buffers[b].size = std::int32_t(g.buffer(b)->size());
      set.buffers[b].gradient = grads[b].data();
    }
    ad::Tape<T> tape(1 << 26);
    std::vector<ad::LeafRecord> log(std::size_t(1) << 24);
    ad::ParamReader<V> reader(&set, &tape, log.data(), std::int32_t(log.size()));
    const FlexiCubesInputs in = g.inputs(true);
    auto t0 = now();
    const FlexiCubesMesh<V> mesh = flexicubes_extract<V>(g.grid, in, reader);
    const double t_extract = seconds_since(t0);
    const std::int32_t base = tape.mark();
    MESSAGE("64^3 sphere: " << mesh.num_triangles() << " triangles, " << mesh.vertices.size() << " vertices; extraction "
                            << t_extract << " s, " << base << " nodes");
    t0 = now();
    const MeshAdjacency adj = mesh_adjacency(mesh.triangles, std::int32_t(mesh.vertices.size()));
    MESSAGE("  adjacency: " << seconds_since(t0) << " s");
    const char* names[8] = {"dilation", "bce", "weight_l1", "dev", "face_area", "developability", "edge_normal", "laplacian"};
    for (int term = 0; term < 8; ++term) {
      tape.rewind(base);
      reader.clear();  // nothing is scattered here: only the tape's size and time matter
      t0 = now();
      V y;
      switch (term) {
        case 0: y = sdf_dilation_loss<V>(g.grid, in.sdf, reader); break;
        case 1: y = sdf_sign_change_bce_loss<V>(g.grid, in.sdf, reader); break;
        case 2: y = flexicubes_weight_l1<V>(in, reader); break;
        case 3: y = flexicubes_dev_loss<V>(g.grid, in, reader, mesh); break;
        case 4: y = mean_face_area(mesh.vertices, mesh.triangles); break;
        case 5: y = developability_loss(mesh.vertices, mesh.triangles, adj); break;
        case 6: y = edge_normal_loss(mesh.vertices, mesh.triangles, adj); break;
        default: y = laplacian_loss(mesh.vertices, adj); break;
      }
      const double t_fwd = seconds_since(t0);
      REQUIRE_FALSE(tape.overflowed());
      t0 = now();
      tape.backward(y);
      const double t_bwd = seconds_since(t0);
      MESSAGE("  " << std::string(names[term]) << ": value " << y.value << ", record " << t_fwd << " s, " << (tape.size() - base)
                   << " nodes (" << double(tape.size() - base) * double(ad::Tape<T>::bytes_per_node) / 1e6
                   << " MB), backward through term + extraction " << t_bwd << " s");
    }
  }
  {
    const Mesh m = torus(200, 125, 1.0, 0.35);  // 50000 faces, 25000 vertices
    auto t0 = now();
    const MeshAdjacency adj = mesh_adjacency(m.t, std::int32_t(m.p.size()));
    MESSAGE("50k-face torus: adjacency " << seconds_since(t0) << " s");
    for (int which = 0; which < 5; ++which) {
      const MeshTerms f{&m, &adj, which};
      t0 = now();
      const double plain = f(m.p);
      const double t_plain = seconds_since(t0);
      std::vector<double> grad;
      int nodes = 0;
      t0 = now();
      reverse_gradient<double>(m.p, f, grad, &nodes, 1 << 26);
      const double t_rev = seconds_since(t0);
      MESSAGE("  " << std::string(mesh_term_names[which]) << ": value " << plain << ", double " << t_plain << " s, Var<double> record + backward "
                   << t_rev << " s, " << nodes << " nodes (" << double(nodes) * double(ad::Tape<T>::bytes_per_node) / 1e6 << " MB)");
    }
  }
}
