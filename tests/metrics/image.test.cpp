// PSNR and SSIM against closed forms (an image against itself, against a
// constant offset of k levels, constant images) and SSIM against a direct,
// unseparated evaluation of Wang et al.'s formula.
#include "difftrans/metrics/image.hpp"

#include <random>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
namespace metrics = difftrans::metrics;

namespace {

// A linear image whose tone-mapped 8-bit levels are exactly `levels` (RGB).
io::Image from_levels(const std::vector<int>& levels, int w, int h) {
  io::Image img(w, h);
  for (size_t i = 0; i < levels.size(); ++i) img.rgb[i] = io::srgb_to_linear(float(levels[i]) / 255.0f);
  return img;
}

std::vector<int> random_levels(int w, int h, int lo, int hi, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<int> v(size_t(w) * size_t(h) * 3);
  for (auto& x : v) x = lo + int(rng() % unsigned(hi - lo + 1));
  return v;
}

// SSIM straight from the definition: for every window position, weighted
// moments over the full 11 x 11 Gaussian window, per channel.
double ssim_direct(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, int w, int h) {
  double g[11][11], sum = 0.0;
  for (int i = 0; i < 11; ++i)
    for (int j = 0; j < 11; ++j) sum += g[i][j] = std::exp(-((i - 5) * (i - 5) + (j - 5) * (j - 5)) / (2.0 * 1.5 * 1.5));
  const double c1 = std::pow(0.01 * 255, 2), c2 = std::pow(0.03 * 255, 2);
  double total = 0.0;
  for (int c = 0; c < 3; ++c) {
    double mean = 0.0;
    for (int y = 0; y + 11 <= h; ++y)
      for (int x = 0; x + 11 <= w; ++x) {
        double ma = 0, mb = 0, saa = 0, sbb = 0, sab = 0;
        for (int i = 0; i < 11; ++i)
          for (int j = 0; j < 11; ++j) {
            const double wt = g[i][j] / sum;
            const size_t k = (size_t(y + i) * size_t(w) + size_t(x + j)) * 3 + size_t(c);
            ma += wt * a[k];
            mb += wt * b[k];
          }
        for (int i = 0; i < 11; ++i)
          for (int j = 0; j < 11; ++j) {
            const double wt = g[i][j] / sum;
            const size_t k = (size_t(y + i) * size_t(w) + size_t(x + j)) * 3 + size_t(c);
            saa += wt * (a[k] - ma) * (a[k] - ma);
            sbb += wt * (b[k] - mb) * (b[k] - mb);
            sab += wt * (a[k] - ma) * (b[k] - mb);
          }
        mean += (2 * ma * mb + c1) * (2 * sab + c2) / ((ma * ma + mb * mb + c1) * (saa + sbb + c2));
      }
    total += mean / double((w - 10) * (h - 10));
  }
  return total / 3.0;
}

}  // namespace

TEST_CASE("an image against itself: PSNR inf, SSIM 1") {
  const io::Image img = from_levels(random_levels(32, 24, 0, 255, 1), 32, 24);
  const io::Mask mask(32, 24, true);
  const auto m = metrics::evaluate_image(img, img, &mask);
  CHECK(std::isinf(m.psnr));
  CHECK(m.psnr > 0);
  CHECK(std::isinf(m.psnr_mask));
  CHECK(m.ssim == doctest::Approx(1.0).epsilon(1e-12));
}

TEST_CASE("constant offset of k levels: PSNR = 20 log10(255 / k), full frame and inside the mask") {
  const int w = 40, h = 30;
  for (const int k : {1, 3, 17}) {
    CAPTURE(k);
    const auto levels = random_levels(w, h, 0, 255 - k, unsigned(k));
    auto shifted = levels;
    for (auto& v : shifted) v += k;
    const io::Image a = from_levels(levels, w, h), b = from_levels(shifted, w, h);
    const auto m = metrics::evaluate_image(a, b);
    CHECK(m.psnr == doctest::Approx(20.0 * std::log10(255.0 / k)).epsilon(1e-12));
    CHECK(std::isnan(m.psnr_mask));  // no mask given
    // offset only inside a mask of 400 of the 1200 pixels (10 rows of 40)
    io::Mask mask(w, h);
    auto partial = levels;
    for (int y = 0; y < 10; ++y)
      for (int x = 0; x < w; ++x) {
        mask.inside[size_t(y * w + x)] = 1;
        for (int c = 0; c < 3; ++c) partial[size_t(y * w + x) * 3 + size_t(c)] += k;
      }
    REQUIRE(mask.count() == 400);
    const auto p = metrics::evaluate_image(from_levels(partial, w, h), a, &mask);
    CHECK(p.psnr_mask == doctest::Approx(20.0 * std::log10(255.0 / k)).epsilon(1e-12));
    CHECK(p.psnr == doctest::Approx(10.0 * std::log10(255.0 * 255.0 / (k * k * 400.0 / 1200.0))).epsilon(1e-12));
  }
}

TEST_CASE("SSIM of constant images: only the luminance term, (2 v (v+k) + C1) / (v^2 + (v+k)^2 + C1)") {
  const int w = 16, h = 13;
  for (const auto& [v, k] : {std::pair<int, int>{100, 20}, {0, 255}, {30, 1}}) {
    const io::Image a = from_levels(std::vector<int>(size_t(w * h * 3), v), w, h);
    const io::Image b = from_levels(std::vector<int>(size_t(w * h * 3), v + k), w, h);
    const double c1 = (0.01 * 255) * (0.01 * 255);
    const double expected = (2.0 * v * (v + k) + c1) / (double(v) * v + double(v + k) * (v + k) + c1);
    CHECK(metrics::evaluate_image(a, b).ssim == doctest::Approx(expected).epsilon(1e-12));
  }
}

TEST_CASE("SSIM equals a direct evaluation of the definition") {
  const int w = 23, h = 17;
  const auto la = random_levels(w, h, 0, 255, 11);
  auto lb = la;
  std::mt19937 rng(5);
  for (auto& v : lb) v = std::clamp(v + int(rng() % 61) - 30, 0, 255);
  const io::Image a = from_levels(la, w, h), b = from_levels(lb, w, h);
  const auto ta = io::tone_map(a), tb = io::tone_map(b);
  const double s = metrics::evaluate_image(a, b).ssim;
  CHECK(s == doctest::Approx(ssim_direct(ta, tb, w, h)).epsilon(1e-10));
  CHECK(s < 0.99);
  CHECK(metrics::evaluate_image(b, a).ssim == doctest::Approx(s).epsilon(1e-12));  // symmetric
}

TEST_CASE("tone mapping comes first; sizes must agree; SSIM needs an 11 x 11 window; empty masks give NaN") {
  io::Image bright(12, 12, 5.0f), one(12, 12, 1.0f);
  CHECK(std::isinf(metrics::evaluate_image(bright, one).psnr));  // both clamp to 255
  CHECK_THROWS_AS(metrics::evaluate_image(io::Image(12, 12), io::Image(12, 11)), std::invalid_argument);
  CHECK_THROWS_AS(metrics::evaluate_image(io::Image(10, 12), io::Image(10, 12)), std::invalid_argument);
  const io::Mask empty(12, 12), wrong(3, 3);
  CHECK(std::isnan(metrics::evaluate_image(bright, one, &empty).psnr_mask));
  CHECK_THROWS_AS(metrics::evaluate_image(bright, one, &wrong), std::invalid_argument);
}
