// A Gaussian blur of an equirectangular environment map (RGB texels, row 0
// at the top), for coarse-to-fine fitting: σ in texels of the map's width,
// separable, wrapping around in longitude and clamped at the poles (the
// horizontal footprint is not widened towards the poles: the blur is meant to
// smooth the loss landscape, not to prefilter exactly). σ <= 0 copies.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace difftrans::scene {

inline std::vector<float> blur_equirect(const std::vector<float>& texels, int width, int height, float sigma) {
  if (!(sigma > 0.0f) || width <= 0 || height <= 0) return texels;
  const int radius = int(std::ceil(3.0f * sigma));
  std::vector<float> kernel(std::size_t(2 * radius + 1));
  float sum = 0.0f;
  for (int k = -radius; k <= radius; ++k) sum += kernel[std::size_t(k + radius)] = std::exp(-0.5f * float(k * k) / (sigma * sigma));
  for (float& w : kernel) w /= sum;
  std::vector<float> rows(texels.size(), 0.0f), out(texels.size(), 0.0f);
  for (int y = 0; y < height; ++y)  // longitude: wraps around
    for (int x = 0; x < width; ++x)
      for (int k = -radius; k <= radius; ++k) {
        const int xs = ((x + k) % width + width) % width;
        const float w = kernel[std::size_t(k + radius)];
        for (int c = 0; c < 3; ++c)
          rows[(std::size_t(y) * width + x) * 3 + c] += w * texels[(std::size_t(y) * width + xs) * 3 + c];
      }
  for (int y = 0; y < height; ++y)  // latitude: clamped at the poles
    for (int x = 0; x < width; ++x)
      for (int k = -radius; k <= radius; ++k) {
        const int ys = std::clamp(y + k, 0, height - 1);
        const float w = kernel[std::size_t(k + radius)];
        for (int c = 0; c < 3; ++c)
          out[(std::size_t(y) * width + x) * 3 + c] += w * rows[(std::size_t(ys) * width + x) * 3 + c];
      }
  return out;
}

}  // namespace difftrans::scene
