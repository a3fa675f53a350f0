// The exposure of LDR photographs: one scale per scene (image = scale ·
// radiance), estimated from the background pixels of a split against a known
// environment as the median of per-pixel ratios (image / environment, summed
// over RGB) over pixels that are neither clipped nor too dark to trust, and
// divided out of a scene's images. The fitted distant environment absorbs any
// global scale by itself; the estimate matters where radiance is compared
// with a given environment (the recovered map against a reference,
// relighting under other maps, a renderer fed the reference map).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "pipeline/environment.hpp"

namespace difftrans::pipeline {

struct ExposureOptions {
  int margin = 2;       // pixels within this many of the mask are left out (as background_mask)
  float clip = 0.98f;   // a pixel with any linear channel at or above this is clipped (8-bit 253 is 0.982)
  float dark = 0.005f;  // pixels whose mean linear channel (image or environment) is below this are left out
  int stride = 1;       // every stride-th pixel in x and y
};

struct ExposureEstimate {
  double scale = std::numeric_limits<double>::quiet_NaN();  // median image / environment; NaN when no pixel was usable
  std::int64_t pixels = 0;   // background pixels used
  std::int64_t clipped = 0;  // background pixels left out as clipped
  std::int64_t dark = 0;     // background pixels left out as too dark (image or environment)
  double q25 = 0.0, q75 = 0.0;  // quartiles of the ratio: how well one scale explains the pixels
};

// The estimate against any radiance(origin, direction) -> Vec3f (a distant
// map ignores the origin). Frames without pixels or without a mask (and not
// environment_only) are skipped.
template <class Radiance>
ExposureEstimate estimate_exposure_with(const io::Split& split, const Radiance& radiance,
                                        const ExposureOptions& opt = {}) {
  ExposureEstimate e;
  std::vector<double> ratios;
  const int stride = std::max(opt.stride, 1);
  for (const io::Frame& f : split.frames) {
    if (f.image.width == 0 || (!f.environment_only && f.mask.width == 0)) continue;
    const scene::Camera cam = camera_of(f);
    const io::Mask bg = background_mask(f, opt.margin);
    for (int y = 0; y < f.image.height; y += stride)
      for (int x = 0; x < f.image.width; x += stride) {
        if (!bg.at(x, y)) continue;
        const Vec3f c = f.image.at(x, y);
        if (std::max(c.x, std::max(c.y, c.z)) >= opt.clip) {
          ++e.clipped;
          continue;
        }
        const scene::Ray r = cam.generate_ray(x, y);
        const Vec3f env = radiance(r.origin, r.direction);
        const double image_sum = double(c.x) + c.y + c.z, env_sum = double(env.x) + env.y + env.z;
        if (!(image_sum >= 3.0 * opt.dark && env_sum >= 3.0 * opt.dark)) {
          ++e.dark;
          continue;
        }
        ratios.push_back(image_sum / env_sum);
      }
  }
  e.pixels = std::int64_t(ratios.size());
  if (ratios.empty()) return e;
  const auto quantile = [&](double q) {
    const auto k = std::size_t(std::llround(q * double(ratios.size() - 1)));
    std::nth_element(ratios.begin(), ratios.begin() + std::ptrdiff_t(k), ratios.end());
    return ratios[k];
  };
  e.q25 = quantile(0.25);
  e.q75 = quantile(0.75);
  e.scale = quantile(0.5);
  return e;
}

inline ExposureEstimate estimate_exposure(const io::Split& split, const scene::EnvMap& env,
                                          const ExposureOptions& opt = {}) {
  return estimate_exposure_with(split, distant_radiance(env), opt);
}

// Divides the pixels of every frame that has them by `scale` (radiance = image / scale).
inline void apply_exposure(io::Split& split, double scale) {
  const float inv = float(1.0 / scale);
  for (io::Frame& f : split.frames)
    for (float& v : f.image.rgb) v *= inv;
}

}  // namespace difftrans::pipeline
