// Adam and AdamUniform: first steps against values computed by hand from the
// update rule, convergence on a badly scaled quadratic, AdamUniform's one
// step scale per tensor, and the learning-rate schedules.
#include "difftrans/optim/adam.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <vector>

using namespace difftrans::optim;

TEST_CASE("Adam: first and second step match the update rule by hand") {
  AdamOptions o;
  o.lr = 0.1f;
  o.beta1 = 0.9f;
  o.beta2 = 0.99f;
  o.eps = 1e-8f;
  Adam adam(2, o);
  std::vector<float> p = {1.0f, -2.0f};
  // step 1: m̂1 = g, m̂2 = g², so each entry moves by lr · sign(g)
  adam.step(p, {0.5f, -4.0f});
  CHECK(p[0] == doctest::Approx(0.9).epsilon(1e-6));
  CHECK(p[1] == doctest::Approx(-1.9).epsilon(1e-6));
  // step 2 with g = (1, 2):
  // g1 = 0.9·0.05 + 0.1·1 = 0.145, g2 = 0.99·0.0025 + 0.01·1 = 0.012475
  // m̂1 = 0.145 / 0.19, m̂2 = 0.012475 / 0.0199
  const double m1a = 0.145 / 0.19, m2a = 0.012475 / 0.0199;
  // entry 1: g1 = 0.9·(−0.4) + 0.1·2 = −0.16, g2 = 0.99·0.16 + 0.01·4 = 0.1984
  const double m1b = -0.16 / 0.19, m2b = 0.1984 / 0.0199;
  adam.step(p, {1.0f, 2.0f});
  CHECK(p[0] == doctest::Approx(0.9 - 0.1 * m1a / (std::sqrt(m2a) + 1e-8)).epsilon(1e-5));
  CHECK(p[1] == doctest::Approx(-1.9 - 0.1 * m1b / (std::sqrt(m2b) + 1e-8)).epsilon(1e-5));
  CHECK(adam.steps() == 2);
}

TEST_CASE("AdamUniform: one step scale for the whole tensor") {
  AdamOptions o;
  o.lr = 0.1f;
  o.beta1 = 0.9f;
  o.beta2 = 0.99f;
  AdamUniform adam(3, o);
  std::vector<float> p = {0.0f, 0.0f, 0.0f};
  const std::vector<float> g = {1.0f, -2.0f, 4.0f};
  adam.step(p, g);
  // step 1: m̂1 = g, max √m̂2 = max |g| = 4, so p = −lr · g / 4: every entry
  // scaled by the same factor, the direction is the gradient's
  CHECK(p[0] == doctest::Approx(-0.025));
  CHECK(p[1] == doctest::Approx(0.05));
  CHECK(p[2] == doctest::Approx(-0.1));
  CHECK(adam.last_scale() == doctest::Approx(0.1 / 4.0));
  // plain Adam instead moves every entry by the same amount lr
  Adam plain(3, o);
  std::vector<float> q = {0.0f, 0.0f, 0.0f};
  plain.step(q, g);
  CHECK(std::abs(q[0]) == doctest::Approx(0.1));
  CHECK(std::abs(q[2]) == doctest::Approx(0.1));
  // step 2, by hand: g1 = 0.9 g + 0.1 g' , g2 = 0.99 g² + 0.01 g'²
  const std::vector<float> g2 = {2.0f, 0.0f, -1.0f};
  std::vector<double> m1(3), m2(3);
  double mx = 0.0;
  for (int i = 0; i < 3; ++i) {
    m1[i] = (0.09 * g[i] + 0.1 * g2[i]) / 0.19;
    m2[i] = (0.0099 * g[i] * g[i] + 0.01 * g2[i] * g2[i]) / 0.0199;
    mx = std::max(mx, std::sqrt(m2[i]));
  }
  const std::vector<float> before = p;
  adam.step(p, g2);
  for (int i = 0; i < 3; ++i) CHECK(p[i] == doctest::Approx(before[i] - 0.1 * m1[i] / (1e-8 + mx)).epsilon(1e-5));
  // the ratio of steps equals the ratio of first moments: one shared scale
  CHECK((p[0] - before[0]) / (p[2] - before[2]) == doctest::Approx(m1[0] / m1[2]).epsilon(1e-4));
}

namespace {

// f(p) = ½ Σ a_i (p_i − c_i)², a badly scaled quadratic.
template <class Opt>
double minimize(Opt& opt, std::vector<float>& p, int iterations, bool decay) {
  const std::vector<float> a = {1.0f, 10.0f, 100.0f, 0.1f}, c = {1.0f, -2.0f, 0.5f, 3.0f};
  std::vector<float> g(p.size());
  for (int it = 0; it < iterations; ++it) {
    for (std::size_t i = 0; i < p.size(); ++i) g[i] = a[i] * (p[i] - c[i]);
    opt.step(p, g, decay ? exponential_lr(0.1f, it, 0.0005f) : 0.05f);
  }
  double err = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) err = std::max(err, std::abs(double(p[i] - c[i])));
  return err;
}

}  // namespace

TEST_CASE("Adam and AdamUniform converge on a quadratic") {
  {
    Adam adam(4);
    std::vector<float> p(4, 0.0f);
    CHECK(minimize(adam, p, 4000, true) < 1e-2);
  }
  {
    AdamUniform adam(4);
    std::vector<float> p(4, 0.0f);
    // the shared scale makes the stiff coordinate set the pace; the soft one (a = 0.1) converges last
    CHECK(minimize(adam, p, 20000, false) < 2e-2);
  }
}

TEST_CASE("learning-rate schedules") {
  CHECK(exponential_lr(0.01f, 0) == doctest::Approx(0.01));
  CHECK(exponential_lr(0.01f, 1000) == doctest::Approx(0.01 * std::pow(10.0, -0.2)));
  CHECK(exponential_lr(0.01f, 5000) == doctest::Approx(0.001));  // one decade per 5000 iterations
  CHECK(step_lr(1e-4f, 1e-3f, 100, 99) == doctest::Approx(1e-4));
  CHECK(step_lr(1e-4f, 1e-3f, 100, 100) == doctest::Approx(1e-3));
  CHECK(warmup_lr(1.0f, 4, 0) == doctest::Approx(0.25));
  CHECK(warmup_lr(1.0f, 4, 10) == doctest::Approx(1.0));
}

TEST_CASE("reset forgets the moments") {
  Adam adam(2);
  std::vector<float> p = {0.0f, 0.0f};
  adam.step(p, {1.0f, 1.0f});
  adam.reset(5);
  CHECK(adam.size() == 5);
  CHECK(adam.steps() == 0);
  for (float v : adam.first_moment()) CHECK(v == 0.0f);
  std::vector<float> q(4);
  CHECK_THROWS(adam.step(q, std::vector<float>(4, 1.0f)));
}

TEST_CASE("state and restore continue a run exactly (checkpoints)") {
  const auto grad_at = [](const std::vector<float>& p, int i) {
    std::vector<float> g(p.size());
    for (std::size_t k = 0; k < p.size(); ++k) g[k] = 2.0f * p[k] - float(k) + 0.1f * float(i % 3);
    return g;
  };
  std::vector<float> straight = {1.0f, -2.0f, 0.5f}, resumed = straight;
  Adam a(3), b(3);
  AdamState saved;
  std::vector<float> saved_p;
  for (int i = 0; i < 20; ++i) {
    a.step(straight, grad_at(straight, i), 0.05f);
    if (i == 9) {
      saved = a.state();
      saved_p = straight;
    }
  }
  CHECK(saved.steps == 10);
  b.restore(saved);
  resumed = saved_p;
  for (int i = 10; i < 20; ++i) b.step(resumed, grad_at(resumed, i), 0.05f);
  CHECK(resumed == straight);  // bit for bit
  CHECK(b.steps() == 20);
  AdamState bad = saved;
  bad.g2.pop_back();
  CHECK_THROWS_AS(b.restore(bad), std::invalid_argument);
}

TEST_CASE("summary: agreement 1 for a repeated gradient, (1 - beta1) / (1 + beta1) for noise; the peak entry") {
  AdamOptions o;
  o.beta1 = 0.9f;
  o.beta2 = 0.999f;
  CHECK(AdamUniform(4, o).summary().agreement == 0.0);  // no step yet
  AdamUniform same(4, o);
  std::vector<float> p(4, 0.0f);
  for (int i = 0; i < 50; ++i) same.step(p, {1.0f, -2.0f, 0.5f, 0.5f}, 1e-3f);
  const auto s = same.summary();
  CHECK(s.agreement == doctest::Approx(1.0).epsilon(1e-4));
  // the largest entry (2) against the RMS of (1, 2, 0.5, 0.5): √(5.5 / 4)
  CHECK(s.peak == doctest::Approx(2.0 / std::sqrt(5.5 / 4.0)).epsilon(1e-4));

  // independent signs, entry by entry and step by step: the mean keeps
  // (1 − β1) / (1 + β1) of the energy once the moments have settled
  Adam noise(2000, o);
  std::vector<float> q(2000, 0.0f), g(2000);
  std::uint64_t state = 12345;
  for (int i = 0; i < 400; ++i) {
    for (float& x : g) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      x = (state >> 63) ? 1.0f : -1.0f;
    }
    noise.step(q, g, 1e-3f);
  }
  const auto n = noise.summary();
  CHECK(n.agreement == doctest::Approx(0.1 / 1.9).epsilon(0.1));
  CHECK(n.peak == doctest::Approx(1.0).epsilon(1e-3));
}
