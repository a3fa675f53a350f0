// The near-field radiance field: the hand-written backward pass of the volume
// renderer against central differences evaluated in double (every raw value
// and the background); its value equals the forward query; skipping empty
// cells changes nothing above the pruning threshold; resampling keeps a
// trilinear field; the smoothness prior's gradient against differences.
// (The fit: radiance_field_fit.test.cpp.)
#include "support/ad_check.hpp"

#include <random>

#include "difftrans/scene/radiance_field.hpp"

using namespace dt_test;
namespace sc = difftrans::scene;

namespace {

// A small field with varied raw values: some dense, some thin.
sc::RadianceField random_field(const Vec3i& res, std::uint32_t seed) {
  sc::RadianceField f(res, Vec3f(-1.0f, -0.8f, -1.2f), Vec3f(1.0f, 0.9f, 1.1f), 0.0f, 0.0f);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dens(-3.0f, 1.5f), col(-1.5f, 1.5f);
  for (std::size_t v = 0; v < f.vertex_count(); ++v) {
    f.values[v * 4] = dens(rng);
    for (int ch = 1; ch < 4; ++ch) f.values[v * 4 + ch] = col(rng);
  }
  f.density_scale = 2.0f;
  f.step_voxels = 0.37f;
  f.min_transmittance = 0.0f;  // no early stop: C is smooth in every value
  f.background = Vec3f(0.3f, 0.5f, 0.2f);
  return f;
}

struct TestRay {
  Vec3d o, d;
  double offset;
};

const std::vector<TestRay>& test_rays() {
  static const std::vector<TestRay> rays = {
      {Vec3d(-3.0, 0.1, 0.2), Vec3d(1.0, 0.05, -0.1), 0.5},   // enters from outside
      {Vec3d(0.1, -0.2, 0.3), Vec3d(-0.3, 0.7, 0.4), 0.13},   // starts inside
      {Vec3d(0.5, 2.0, -0.4), Vec3d(-0.2, -1.0, 0.3), 0.81},  // from above
      {Vec3d(0.0, 0.0, 0.0), Vec3d(0.0, 0.0, 1.0), 0.5},      // along an axis
  };
  return rays;
}

const Vec3d loss_weight(0.7, -1.1, 0.4);

// Σ over the test rays of loss_weight · C, evaluated in double.
double loss(const sc::RadianceField& f) {
  const sc::RadianceFieldView v = f.view();
  double sum = 0;
  for (const TestRay& r : test_rays()) sum += glm::dot(loss_weight, sc::field_radiance<double>(v, r.o, r.d, r.offset));
  return sum;
}

}  // namespace

TEST_CASE("radiance field: the backward pass matches central differences for every raw value and the background") {
  sc::RadianceField f = random_field(Vec3i(4, 5, 3), 7);
  std::vector<double> grad(f.values.size(), 0.0), grad_bg(3, 0.0);
  std::vector<sc::FieldSampleRecord<double>> scratch;
  double value = 0;
  for (const TestRay& r : test_rays()) {
    const Vec3d C = sc::field_radiance_backward<double>(
        f.view(), r.o, r.d, r.offset, [](const Vec3d&) { return loss_weight; }, grad.data(), grad_bg.data(), scratch);
    // the backward pass's value is the forward query's
    const Vec3d F = sc::field_radiance<double>(f.view(), r.o, r.d, r.offset);
    for (int c = 0; c < 3; ++c) CHECK(C[c] == doctest::Approx(F[c]).epsilon(1e-12));
    CHECK(!scratch.empty());
    value += glm::dot(loss_weight, C);
  }
  CHECK(value == doctest::Approx(loss(f)).epsilon(1e-12));

  // differences: perturb the float value and divide by the change actually stored
  const auto difference = [&](float& x) {
    const float x0 = x, h = 1e-3f * std::max(1.0f, std::abs(x0));
    x = x0 + h;
    const float xp = x;
    const double lp = loss(f);
    x = x0 - h;
    const float xm = x;
    const double lm = loss(f);
    x = x0;
    return (lp - lm) / (double(xp) - double(xm));
  };
  double max_grad = 0;
  for (double g : grad) max_grad = std::max(max_grad, std::abs(g));
  REQUIRE(max_grad > 1e-3);
  int nonzero = 0;
  for (std::size_t i = 0; i < f.values.size(); ++i) {
    const double fd = difference(f.values[i]);
    INFO("value " << i << " (channel " << i % 4 << "): backward " << grad[i] << ", differences " << fd);
    CHECK(std::abs(grad[i] - fd) <= 1e-5 * max_grad + 1e-6 * std::abs(fd));
    nonzero += std::abs(grad[i]) > 1e-8;
  }
  CHECK(nonzero > int(f.values.size()) / 4);  // the rays touch a good part of the grid
  for (int c = 0; c < 3; ++c) {
    const double fd = difference(f.background[c]);
    INFO("background " << c << ": backward " << grad_bg[std::size_t(c)] << ", differences " << fd);
    CHECK(std::abs(grad_bg[std::size_t(c)] - fd) <= 1e-6 + 1e-5 * std::abs(fd));
  }
}

TEST_CASE("radiance field: float forward and backward agree with double; early termination is consistent") {
  sc::RadianceField f = random_field(Vec3i(6, 6, 6), 3);
  f.min_transmittance = 0.05f;
  for (const TestRay& r : test_rays()) {
    const Vec3f o(r.o), d(r.d);
    std::vector<float> g(f.values.size(), 0.0f), gb(3, 0.0f);
    std::vector<sc::FieldSampleRecord<float>> scratch;
    const Vec3f Cb = sc::field_radiance_backward<float>(
        f.view(), o, d, float(r.offset), [](const Vec3f&) { return Vec3f(1.0f); }, g.data(), gb.data(), scratch);
    const Vec3f Cf = sc::field_radiance<float>(f.view(), o, d, float(r.offset));
    const Vec3d Cd = sc::field_radiance<double>(f.view(), r.o, r.d, r.offset);
    for (int c = 0; c < 3; ++c) {
      CHECK(Cb[c] == Cf[c]);
      CHECK(double(Cf[c]) == doctest::Approx(Cd[c]).epsilon(1e-5));
    }
  }
}

TEST_CASE("radiance field: skipping empty cells changes nothing above the threshold") {
  sc::RadianceField f = random_field(Vec3i(9, 9, 9), 11);
  f.min_transmittance = 0.0f;
  // empty the left half: σ tiny there
  for (int k = 0; k < 9; ++k)
    for (int j = 0; j < 9; ++j)
      for (int i = 0; i < 5; ++i) f.values[((std::size_t(k) * 9 + j) * 9 + i) * 4] = -30.0f;
  const std::vector<TestRay>& rays = test_rays();
  std::vector<Vec3d> before;
  for (const TestRay& r : rays) before.push_back(sc::field_radiance<double>(f.view(), r.o, r.d, r.offset));
  f.update_occupancy(1e-6f);
  std::size_t empty = 0;
  for (auto o : f.occupancy) empty += o == 0;
  CHECK(empty == std::size_t(4 * 8 * 8));  // the cells between the emptied vertex columns 0..4
  for (std::size_t n = 0; n < rays.size(); ++n) {
    const Vec3d after = sc::field_radiance<double>(f.view(), rays[n].o, rays[n].d, rays[n].offset);
    for (int c = 0; c < 3; ++c) CHECK(after[c] == doctest::Approx(before[n][c]).epsilon(1e-9));
  }
  // a threshold above the field's density skips everything: only the background is left
  f.update_occupancy(1e9f);
  const Vec3d bg = sc::field_radiance<double>(f.view(), rays[0].o, rays[0].d, 0.5);
  CHECK(bg.x == doctest::Approx(0.3));
  CHECK(bg.y == doctest::Approx(0.5));
  CHECK(bg.z == doctest::Approx(0.2));
}

TEST_CASE("radiance field: resampling keeps a trilinear field; box and resolution are checked") {
  sc::RadianceField f(Vec3i(3, 4, 5), Vec3f(-1.0f), Vec3f(2.0f, 1.0f, 1.5f), 0.0f, 0.0f);
  const auto linear = [](const Vec3d& p, int ch) { return 0.3 * p.x - 0.7 * p.y + 0.2 * p.z + ch; };
  const auto vertex = [](const sc::RadianceField& g, int i, int j, int k) {
    const Vec3f s = g.spacing();
    return Vec3d(g.lo) + Vec3d(i * s.x, j * s.y, k * s.z);
  };
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 3; ++i)
        for (int ch = 0; ch < 4; ++ch)
          f.values[((std::size_t(k) * 4 + j) * 3 + i) * 4 + ch] = float(linear(vertex(f, i, j, k), ch));
  const sc::RadianceField g = f.resampled(Vec3i(7, 6, 9));
  REQUIRE(g.values.size() == std::size_t(7 * 6 * 9 * 4));
  for (int k = 0; k < 9; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 7; ++i)
        for (int ch = 0; ch < 4; ++ch)
          CHECK(g.values[((std::size_t(k) * 6 + j) * 7 + i) * 4 + ch] ==
                doctest::Approx(linear(vertex(g, i, j, k), ch)).epsilon(1e-5));
  CHECK_THROWS_AS(sc::RadianceField(Vec3i(1, 4, 4), Vec3f(0.0f), Vec3f(1.0f), 0.0f, 0.0f), std::invalid_argument);
  CHECK_THROWS_AS(sc::RadianceField(Vec3i(4), Vec3f(0.0f), Vec3f(1.0f, 0.0f, 1.0f), 0.0f, 0.0f), std::invalid_argument);
}

TEST_CASE("radiance field: the smoothness prior's gradient matches differences") {
  sc::RadianceField f = random_field(Vec3i(4, 3, 5), 5);
  std::vector<float> g(f.values.size(), 0.0f);
  const float wd = 0.3f, wc = 0.05f;
  const double e = sc::add_smoothness_gradient(f, wd, wc, g.data());
  CHECK(e > 0.0);
  for (std::size_t i = 0; i < f.values.size(); i += 3) {
    const float x0 = f.values[i];
    std::vector<float> scratch(f.values.size(), 0.0f);
    f.values[i] = x0 + 1e-2f;
    const float xp = f.values[i];
    const double ep = sc::add_smoothness_gradient(f, wd, wc, scratch.data());
    f.values[i] = x0 - 1e-2f;
    const float xm = f.values[i];
    const double em = sc::add_smoothness_gradient(f, wd, wc, scratch.data());
    f.values[i] = x0;
    const double fd = (ep - em) / (double(xp) - double(xm));  // exact for a quadratic, up to rounding
    CHECK(double(g[i]) == doctest::Approx(fd).epsilon(1e-3).scale(1.0));
  }
}
