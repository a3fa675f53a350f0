// The large-steps parameterization: the Laplacian's structure, M x = u round
// trips, the backward pass against finite differences of a loss through
// x(u), factor reuse while the topology stays, and the smoothing effect of
// the reparameterized gradient step.
#include "difftrans/optim/large_steps.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <random>
#include <vector>

#include "support/shapes.hpp"

using namespace difftrans::optim;

namespace {

std::vector<float> random_field(std::size_t n, unsigned seed, float scale = 1.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(-scale, scale);
  std::vector<float> v(n);
  for (float& x : v) x = d(rng);
  return v;
}

}  // namespace

TEST_CASE("uniform Laplacian of a box: degrees, −1 per edge, zero row sums") {
  const dt_test::Shape box = dt_test::make_box(1, 1, 1);
  const SparseMatrixd L = uniform_laplacian(box.triangles.data(), std::int32_t(box.triangles.size() / 3), 8);
  const auto edges = mesh_edges(box.triangles.data(), std::int32_t(box.triangles.size() / 3));
  CHECK(edges.size() == 18);  // 12 box edges + 6 face diagonals
  double trace = 0.0;
  for (int i = 0; i < 8; ++i) {
    double row = 0.0;
    for (int j = 0; j < 8; ++j) row += L.coeff(i, j);
    CHECK(row == doctest::Approx(0.0));
    trace += L.coeff(i, i);
  }
  CHECK(trace == doctest::Approx(2.0 * 18));
  for (const auto& [a, b] : edges) CHECK(L.coeff(a, b) == -1.0);
}

TEST_CASE("M x = u round trip") {
  const dt_test::Shape s = dt_test::make_icosphere(1.0f, 3);
  const std::int32_t nv = std::int32_t(s.positions.size() / 3);
  for (double lambda : {1.0, 19.0, 200.0}) {
    LargeSteps ls(lambda);
    ls.set_topology(s.triangles, nv);
    const std::vector<float> x = random_field(s.positions.size(), 3);
    const std::vector<float> u = ls.to_u(x);
    // u against an independent M x: x + λ Σ_j (x_i − x_j) over neighbours
    std::vector<double> mx(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) mx[i] = x[i];
    for (const auto& [a, b] : mesh_edges(s.triangles.data(), std::int32_t(s.triangles.size() / 3)))
      for (int c = 0; c < 3; ++c) {
        const double d = double(x[3 * a + c]) - double(x[3 * b + c]);
        mx[3 * a + c] += lambda * d;
        mx[3 * b + c] -= lambda * d;
      }
    double err_u = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) err_u = std::max(err_u, std::abs(mx[i] - u[i]) / (1.0 + std::abs(mx[i])));
    CHECK(err_u < 1e-5);
    const std::vector<float> back = ls.from_u(u);
    double err = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) err = std::max(err, double(std::abs(back[i] - x[i])));
    CHECK(err < 1e-4 * (1.0 + lambda * 1e-2));
  }
}

TEST_CASE("backward equals the transpose solve: finite differences of a loss through x(u)") {
  const dt_test::Shape s = dt_test::make_icosphere(1.0f, 1);
  const std::int32_t nv = std::int32_t(s.positions.size() / 3);
  LargeSteps ls(5.0);
  ls.set_topology(s.triangles, nv);
  const std::vector<float> u0 = ls.to_u(s.positions);
  const std::vector<float> w = random_field(u0.size(), 7);
  // loss(x) = Σ w_i x_i + ½ Σ x_i² (nonlinear in x), dloss/dx = w + x
  const auto loss = [&](const std::vector<double>& ud) {
    std::vector<float> uf(ud.begin(), ud.end());
    const std::vector<float> x = ls.from_u(uf);
    double l = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) l += double(w[i]) * x[i] + 0.5 * double(x[i]) * x[i];
    return l;
  };
  const std::vector<float> x0 = ls.from_u(u0);
  std::vector<float> gx(x0.size());
  for (std::size_t i = 0; i < x0.size(); ++i) gx[i] = w[i] + x0[i];
  const std::vector<float> gu = ls.backward(gx);
  std::mt19937 rng(1);
  int checked = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const std::size_t i = std::size_t(rng() % u0.size());
    std::vector<double> up(u0.begin(), u0.end()), um = up;
    const double h = 1e-2;
    up[i] += h;
    um[i] -= h;
    const double fd = (loss(up) - loss(um)) / (2 * h);
    CHECK(gu[i] == doctest::Approx(fd).epsilon(2e-3).scale(1e-3));
    ++checked;
  }
  CHECK(checked == 24);
}

TEST_CASE("the factor is reused while the topology stays") {
  const dt_test::Shape s = dt_test::make_icosphere(1.0f, 2);
  const std::int32_t nv = std::int32_t(s.positions.size() / 3);
  LargeSteps ls(19.0);
  CHECK(ls.set_topology(s.triangles, nv));
  CHECK(ls.factorizations() == 1);
  const std::vector<float> u = random_field(s.positions.size(), 5);
  const std::vector<float> x1 = ls.from_u(u);
  // same topology (a copy of the array): no refactorization, same answer
  const std::vector<std::int32_t> copy = s.triangles;
  CHECK_FALSE(ls.set_topology(copy, nv));
  CHECK(ls.factorizations() == 1);
  const std::vector<float> x2 = ls.from_u(u);
  for (std::size_t i = 0; i < x1.size(); ++i) CHECK(x1[i] == x2[i]);
  // a different topology (one triangle's winding turned; same edges, but the
  // array differs) refactorizes; so does a new λ
  std::vector<std::int32_t> other = s.triangles;
  std::swap(other[1], other[2]);
  CHECK(ls.set_topology(other, nv));
  CHECK(ls.factorizations() == 2);
  ls.set_lambda(3.0);
  CHECK(ls.set_topology(other, nv));
  CHECK(ls.factorizations() == 3);
  CHECK_FALSE(ls.set_topology(other, nv));
  CHECK(ls.factorizations() == 3);
}

TEST_CASE("the reparameterized gradient step is smoother than the plain one") {
  const dt_test::Shape s = dt_test::make_icosphere(1.0f, 3);
  const std::int32_t nv = std::int32_t(s.positions.size() / 3);
  LargeSteps ls(19.0);
  ls.set_topology(s.triangles, nv);
  // a noisy gradient: a smooth component plus per-vertex noise
  std::vector<float> g = random_field(s.positions.size(), 11);
  for (std::int32_t v = 0; v < nv; ++v) g[3 * v] += 2.0f * s.positions[3 * v + 2];
  // plain step: dx = −g. Large steps: du = −M⁻¹ g (gradient w.r.t. u), so dx = M⁻¹ du = −M⁻² g
  const std::vector<float> du = ls.backward(g);
  const std::vector<float> dx = ls.from_u(du);
  const auto normalized_energy = [&](const std::vector<float>& d) {
    double n2 = 0.0;
    for (float v : d) n2 += double(v) * v;
    return laplacian_energy(ls.laplacian(), d.data()) / n2;  // Rayleigh quotient: scale-free roughness
  };
  const double plain = normalized_energy(g), large = normalized_energy(dx);
  MESSAGE("Rayleigh quotient of the update: plain " << plain << ", large steps " << large);
  CHECK(large < 0.05 * plain);
  // and the identity λ = 0 changes nothing
  LargeSteps id(0.0);
  id.set_topology(s.triangles, nv);
  const std::vector<float> same = id.from_u(id.backward(g));
  CHECK(normalized_energy(same) == doctest::Approx(plain).epsilon(1e-4));
}

TEST_CASE("LargeStepsOptimizer moves a noisy sphere toward a target") {
  const dt_test::Shape s = dt_test::make_icosphere(1.0f, 2);
  std::vector<float> x = s.positions;
  std::vector<float> target = s.positions;
  for (float& v : target) v *= 1.5f;  // the larger sphere
  LargeStepsOptimizer opt(10.0);
  opt.reset(x, s.triangles);
  std::vector<float> g(x.size());
  double err0 = 0.0, err = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) err0 = std::max(err0, double(std::abs(x[i] - target[i])));
  for (int it = 0; it < 300; ++it) {
    for (std::size_t i = 0; i < x.size(); ++i) g[i] = x[i] - target[i];
    opt.step(x, g, 0.01f);
  }
  for (std::size_t i = 0; i < x.size(); ++i) err = std::max(err, double(std::abs(x[i] - target[i])));
  CHECK(err < 0.1 * err0);
  CHECK(opt.parameterization().factorizations() == 1);
}

TEST_CASE("LargeStepsOptimizer::change_lambda keeps the positions and reaches detail a constant large λ cannot") {
  const dt_test::Shape s = dt_test::make_icosphere(1.0f, 3);
  const std::int32_t nv = std::int32_t(s.positions.size() / 3);
  // the target: the sphere with a per-vertex radial bump (fine detail)
  std::vector<float> target = s.positions;
  const std::vector<float> bumps = random_field(std::size_t(nv), 5, 0.05f);
  for (std::int32_t v = 0; v < nv; ++v)
    for (int c = 0; c < 3; ++c) target[3 * v + c] *= 1.2f + bumps[std::size_t(v)];
  const auto error = [&](const std::vector<float>& x) {
    double e = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) e += std::abs(double(x[i]) - double(target[i]));
    return e / double(x.size());
  };
  const auto fit = [&](const std::vector<double>& lambdas, int steps_each, LargeStepsOptimizer& opt) {
    std::vector<float> x = s.positions;
    opt.set_lambda(lambdas.front());
    opt.reset(x, s.triangles);
    std::vector<float> g(x.size());
    for (double lambda : lambdas) {
      const std::vector<float> before = x;
      opt.change_lambda(lambda, x);
      CHECK(x == before);  // a new λ moves nothing by itself
      for (int it = 0; it < steps_each; ++it) {
        for (std::size_t i = 0; i < x.size(); ++i) g[i] = x[i] - target[i];
        opt.step(x, g, 0.005f);
      }
    }
    return x;
  };

  SUBCASE("u = M x after the change; the same λ is no change") {
    LargeStepsOptimizer opt(10.0);
    std::vector<float> x = s.positions;
    opt.reset(x, s.triangles);
    CHECK_FALSE(opt.change_lambda(10.0, x));
    CHECK(opt.parameterization().factorizations() == 1);
    x = random_field(x.size(), 9);
    CHECK(opt.change_lambda(2.0, x));
    CHECK(opt.lambda() == 2.0);
    CHECK(opt.parameterization().factorizations() == 2);
    LargeSteps ref(2.0);
    ref.set_topology(s.triangles, nv);
    const std::vector<float> u = ref.to_u(x);
    for (std::size_t i = 0; i < u.size(); ++i) CHECK(opt.u()[i] == doctest::Approx(u[i]).epsilon(1e-5));
    CHECK(opt.adam().steps() == 0);  // the moments restarted
  }
  SUBCASE("coarse to fine against a constant λ, the same number of steps") {
    LargeStepsOptimizer constant(10.0), schedule(10.0);
    const double e0 = error(s.positions);
    const double e_constant = error(fit({10.0, 10.0, 10.0}, 100, constant));
    const double e_schedule = error(fit({10.0, 2.0, 0.5}, 100, schedule));
    MESSAGE("mean |x - target|: start " << e0 << ", λ 10 throughout " << e_constant << ", λ 10 -> 2 -> 0.5 "
                                        << e_schedule);
    CHECK(constant.parameterization().factorizations() == 1);
    CHECK(schedule.parameterization().factorizations() == 3);
    CHECK(e_schedule < 0.7 * e_constant);
  }
}
