// Least-squares environment fit: a known map is recovered exactly from
// noiseless observations that see every texel; unseen directions get
// finite, smooth values; coverage and residuals are reported truthfully.
#include "support/ad_check.hpp"

#include "difftrans/scene/envmap_fit.hpp"

using namespace dt_test;
namespace sc = difftrans::scene;

namespace {
// A smooth but non-trivial map.
std::vector<float> known_map(int W, int H) {
  std::vector<float> t;
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c)
      t.insert(t.end(), {1.0f + 0.5f * std::sin(0.7f * c), 0.5f + 0.3f * std::cos(0.9f * r), 0.2f + 0.01f * float(r * c % 17)});
  return t;
}

std::vector<sc::EnvObservation> observe(const std::vector<float>& texels, int W, int H, int count, bool upper_only) {
  const sc::EnvMap map = sc::equirect_environment(texels.data(), W, H);
  ad::ParamReader<float> reader(nullptr);
  std::vector<sc::EnvObservation> obs;
  std::uint32_t state = 12345;
  const auto uniform = [&] {
    state = state * 1664525u + 1013904223u;
    return float(state >> 8) / float(1u << 24);
  };
  while (int(obs.size()) < count) {
    const float z = 2 * uniform() - 1, phi = 6.2831853f * uniform(), s = std::sqrt(1 - z * z);
    const Vec3f d(s * std::cos(phi), z, s * std::sin(phi));
    if (upper_only && d.y < 0.1f) continue;
    obs.push_back({d, sc::lookup(reader, map, d)});
  }
  return obs;
}
}  // namespace

TEST_CASE("noiseless observations that see every texel recover the map exactly") {
  const int W = 24, H = 12;
  const auto truth = known_map(W, H);
  sc::EnvFitOptions opt;
  opt.width = W;
  opt.height = H;
  opt.smoothness = 1e-9;  // data alone determines the map
  const sc::EnvFit fit = sc::fit_environment(observe(truth, W, H, 40000, false), opt);
  CHECK(fit.seen_fraction == doctest::Approx(1.0));
  double worst = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) worst = std::max(worst, double(std::abs(fit.texels[i] - truth[i])));
  CHECK(worst < 1e-4);
  CHECK(fit.rms_residual < 1e-5);
}

TEST_CASE("unseen directions are filled with finite, smooth values") {
  const int W = 32, H = 16;
  const auto truth = known_map(W, H);
  sc::EnvFitOptions opt;
  opt.width = W;
  opt.height = H;
  const sc::EnvFit fit = sc::fit_environment(observe(truth, W, H, 20000, true), opt);
  CHECK(fit.seen_fraction > 0.3);
  CHECK(fit.seen_fraction < 0.7);  // the lower hemisphere was never seen
  double jump = 0;
  for (int r = H / 2 + 2; r < H; ++r)  // well inside the unseen part
    for (int c = 0; c < W; ++c)
      for (int ch = 0; ch < 3; ++ch) {
        const float v = fit.texels[std::size_t((r * W + c) * 3 + ch)];
        REQUIRE(std::isfinite(v));
        const float right = fit.texels[std::size_t((r * W + (c + 1) % W) * 3 + ch)];
        const float down = r + 1 < H ? fit.texels[std::size_t(((r + 1) * W + c) * 3 + ch)] : v;
        jump = std::max(jump, double(std::max(std::abs(v - right), std::abs(v - down))));
      }
  double data_jump = 0;  // the largest neighbour difference of the truth itself
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c)
      for (int ch = 0; ch < 3; ++ch)
        data_jump = std::max(data_jump, double(std::abs(truth[std::size_t((r * W + c) * 3 + ch)] -
                                                        truth[std::size_t((r * W + (c + 1) % W) * 3 + ch)])));
  CHECK(jump < data_jump);  // the fill is smoother than the data
  // the seen part is still fitted closely
  CHECK(fit.rms_residual < 0.02);
}

TEST_CASE("bad input is refused with a reason") {
  sc::EnvFitOptions opt;
  CHECK_THROWS_WITH_AS(sc::fit_environment({}, opt), doctest::Contains("no background observations"), std::invalid_argument);
  std::vector<sc::EnvObservation> nan_only{{Vec3f(0, 1, 0), Vec3f(std::nanf(""), 0, 0)}};
  CHECK_THROWS_WITH_AS(sc::fit_environment(nan_only, opt), doctest::Contains("no finite observation"), std::invalid_argument);
  opt.width = 2;
  CHECK_THROWS_AS(sc::fit_environment({{Vec3f(0, 1, 0), Vec3f(1)}}, opt), std::invalid_argument);
  CHECK(sc::envmap_width_for(40.0 / 256 * 3.14159 / 180) == 1024);
  CHECK(sc::envmap_width_for(0.05) == 126);
}
