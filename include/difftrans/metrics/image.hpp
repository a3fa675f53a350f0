// Image metrics of docs/metrics.md, on images tone-mapped to 8 bits (exposure 1,
// clamp, sRGB): PSNR over the frame and inside the object mask, and SSIM
// (Wang et al. 2004: Gaussian window 11, sigma 1.5, K1 0.01, K2 0.03, per
// channel, averaged; the window stays inside the image, "valid" filtering).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/io/image.hpp"

namespace difftrans::metrics {

struct ImageMetrics {
  double psnr = 0.0;
  double psnr_mask = std::numeric_limits<double>::quiet_NaN();  // NaN without a mask or with an empty one
  double ssim = 0.0;
};

// 8-bit RGB interleaved, as io::tone_map writes it.
struct Image8View {
  const std::uint8_t* rgb;
  int width;
  int height;
};

namespace detail {

inline void require_same_size(int w1, int h1, int w2, int h2, const char* what) {
  if (w1 != w2 || h1 != h2)
    throw std::invalid_argument(std::string(what) + ": sizes differ (" + std::to_string(w1) + " x " + std::to_string(h1) +
                                " and " + std::to_string(w2) + " x " + std::to_string(h2) + ")");
}

inline double psnr_from_mse(double mse) {
  return mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : std::numeric_limits<double>::infinity();
}

}  // namespace detail

// PSNR in dB of 8-bit images (peak 255), over every channel of every pixel,
// or of the pixels where mask != 0 if a mask is given. +inf when equal; NaN
// for an empty mask.
inline double psnr(const Image8View& a, const Image8View& b, const io::Mask* mask = nullptr) {
  detail::require_same_size(a.width, a.height, b.width, b.height, "psnr");
  if (mask) detail::require_same_size(a.width, a.height, mask->width, mask->height, "psnr (mask)");
  const std::size_t n = std::size_t(a.width) * std::size_t(a.height);
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t p = 0; p < n; ++p) {
    if (mask && !mask->inside[p]) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.rgb[p * 3 + size_t(c)]) - double(b.rgb[p * 3 + size_t(c)]);
      sum += d * d;
    }
    count += 3;
  }
  if (count == 0) return std::numeric_limits<double>::quiet_NaN();
  return detail::psnr_from_mse(sum / double(count));
}

// Mean SSIM of 8-bit images (dynamic range L = 255) over the positions where
// the 11 x 11 window fits, averaged over R, G, B. Needs at least 11 x 11 pixels.
inline double ssim(const Image8View& a, const Image8View& b) {
  detail::require_same_size(a.width, a.height, b.width, b.height, "ssim");
  constexpr int radius = 5, size = 2 * radius + 1;
  if (a.width < size || a.height < size)
    throw std::invalid_argument("ssim: the image is smaller than the 11 x 11 window");
  double g[size], gsum = 0.0;
  for (int i = 0; i < size; ++i) gsum += g[i] = std::exp(-double((i - radius) * (i - radius)) / (2.0 * 1.5 * 1.5));
  for (double& v : g) v /= gsum;
  const double c1 = (0.01 * 255.0) * (0.01 * 255.0), c2 = (0.03 * 255.0) * (0.03 * 255.0);
  const int w = a.width, h = a.height, ow = w - size + 1, oh = h - size + 1;
  // Horizontal pass into 5 moment images (x, y, xx, yy, xy) of ow x h, then vertical.
  std::vector<double> row(std::size_t(ow) * std::size_t(h) * 5);
  double total = 0.0;
  for (int c = 0; c < 3; ++c) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < ow; ++x) {
        double m[5] = {0, 0, 0, 0, 0};
        for (int k = 0; k < size; ++k) {
          const std::size_t i = (std::size_t(y) * std::size_t(w) + std::size_t(x + k)) * 3 + std::size_t(c);
          const double u = a.rgb[i], v = b.rgb[i];
          m[0] += g[k] * u;
          m[1] += g[k] * v;
          m[2] += g[k] * u * u;
          m[3] += g[k] * v * v;
          m[4] += g[k] * u * v;
        }
        for (int q = 0; q < 5; ++q) row[(std::size_t(y) * std::size_t(ow) + std::size_t(x)) * 5 + std::size_t(q)] = m[q];
      }
    double sum = 0.0;
    for (int y = 0; y < oh; ++y)
      for (int x = 0; x < ow; ++x) {
        double m[5] = {0, 0, 0, 0, 0};
        for (int k = 0; k < size; ++k)
          for (int q = 0; q < 5; ++q)
            m[q] += g[k] * row[(std::size_t(y + k) * std::size_t(ow) + std::size_t(x)) * 5 + std::size_t(q)];
        const double mu_a = m[0], mu_b = m[1];
        const double var_a = m[2] - mu_a * mu_a, var_b = m[3] - mu_b * mu_b, cov = m[4] - mu_a * mu_b;
        sum += ((2.0 * mu_a * mu_b + c1) * (2.0 * cov + c2)) /
               ((mu_a * mu_a + mu_b * mu_b + c1) * (var_a + var_b + c2));
      }
    total += sum / (double(ow) * double(oh));
  }
  return total / 3.0;
}

// PSNR, PSNR inside the mask (if given) and SSIM of two linear images, both
// tone-mapped as docs/conventions.md says first.
inline ImageMetrics evaluate_image(const io::Image& predicted, const io::Image& truth, const io::Mask* mask = nullptr) {
  detail::require_same_size(predicted.width, predicted.height, truth.width, truth.height, "evaluate_image");
  const auto a = io::tone_map(predicted), b = io::tone_map(truth);
  const Image8View va{a.data(), predicted.width, predicted.height}, vb{b.data(), truth.width, truth.height};
  ImageMetrics m;
  m.psnr = psnr(va, vb);
  if (mask) m.psnr_mask = psnr(va, vb, mask);
  m.ssim = ssim(va, vb);
  return m;
}

}  // namespace difftrans::metrics
