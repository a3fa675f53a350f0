// Background pixels of a scene directory as environment observations: the
// ray through each pixel centre that the object's mask leaves out (minus a
// margin around the mask), with the pixel's radiance; and the comparison of
// a fitted environment with held-out background pixels. The environment is
// a distant map (EnvMap) or any radiance(origin, direction) (a near field).
#pragma once

#include <vector>

#include "difftrans/core/parallel.hpp"
#include "difftrans/io/dataset.hpp"
#include "difftrans/metrics/image.hpp"
#include "difftrans/render/views.hpp"
#include "difftrans/scene/envmap_fit.hpp"

namespace difftrans::render {

struct BackgroundOptions {
  int margin = 2;  // pixels within this many pixels (Chebyshev) of the mask are left out
  int stride = 1;  // use every stride-th pixel in x and y
};

// 1 where a pixel is background and at least `margin` pixels from the mask.
inline io::Mask background_mask(const io::Frame& f, int margin) {
  const int w = f.image.width, h = f.image.height;
  io::Mask bg(w, h, true);
  if (f.environment_only || f.mask.width == 0) return bg;
  // separable max filter of the mask: dilation by a (2 margin + 1)² square
  std::vector<std::uint8_t> rows(std::size_t(w) * h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      bool any = false;
      for (int dx = -margin; dx <= margin && !any; ++dx) {
        const int xx = x + dx;
        any = xx >= 0 && xx < w && f.mask.at(xx, y);
      }
      rows[std::size_t(y) * w + x] = any;
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      bool any = false;
      for (int dy = -margin; dy <= margin && !any; ++dy) {
        const int yy = y + dy;
        any = yy >= 0 && yy < h && rows[std::size_t(yy) * w + x];
      }
      bg.inside[std::size_t(y) * w + x] = !any;
    }
  return bg;
}

// The camera of a frame (pinhole intrinsics, camera-to-world).
inline scene::Camera camera_of(const io::Frame& f) {
  const auto& k = f.intrinsics;
  return camera_from(f.camera_to_world, k.fx, k.fy, k.cx, k.cy, k.width, k.height);
}

// Observations from every frame of a split whose pixels were read. Frames
// with neither a mask nor environment_only cannot tell background from
// object and are skipped (their names are added to `skipped`).
inline std::vector<scene::EnvObservation> background_observations(const io::Split& split,
                                                                  const BackgroundOptions& opt = {},
                                                                  std::vector<std::string>* skipped = nullptr) {
  std::vector<scene::EnvObservation> obs;
  const int stride = opt.stride < 1 ? 1 : opt.stride;
  for (const io::Frame& f : split.frames) {
    if (f.image.width == 0 || (!f.environment_only && f.mask.width == 0)) {
      if (skipped) skipped->push_back(f.name);
      continue;
    }
    const scene::Camera cam = camera_of(f);
    const io::Mask bg = background_mask(f, opt.margin);
    for (int y = 0; y < f.image.height; y += stride)
      for (int x = 0; x < f.image.width; x += stride) {
        if (!bg.at(x, y)) continue;
        const scene::Ray r = cam.generate_ray(x, y);
        obs.push_back({r.direction, f.image.at(x, y), 1.0f, r.origin});
      }
  }
  return obs;
}

// The background pixels of a frame as a near-field environment would show
// them: radiance(origin, direction) -> Vec3f along each pixel-centre ray, rows
// on the thread pool (object pixels are copied from the image so that only
// background differs).
template <class Radiance>
io::Image environment_view_with(const io::Frame& f, const Radiance& radiance) {
  const scene::Camera cam = camera_of(f);
  io::Image out = f.image;
  const io::Mask bg = background_mask(f, 0);
  parallel_for(out.height, 1, [&](std::int64_t y0, std::int64_t y1, int) {
    for (int y = int(y0); y < int(y1); ++y)
      for (int x = 0; x < out.width; ++x)
        if (bg.at(x, y)) {
          const scene::Ray r = cam.generate_ray(x, y);
          out.set(x, y, radiance(r.origin, r.direction));
        }
  });
  return out;
}

// A distant environment as the radiance(origin, direction) callable that the
// *_with functions take: the origin does not matter.
inline auto distant_radiance(const scene::EnvMap& env) {
  return [&env](const Vec3f&, const Vec3f& d) {
    ad::ParamReader<float> reader(nullptr);
    return scene::lookup(reader, env, d);
  };
}

// The same for a distant map.
inline io::Image environment_view(const io::Frame& f, const scene::EnvMap& env) {
  return environment_view_with(f, distant_radiance(env));
}

// PSNR (docs/metrics.md) of the environment against the background
// pixels of held-out frames, over all their background pixels together;
// radiance(origin, direction) as for environment_view_with.
template <class Radiance>
double background_psnr_with(const io::Split& split, const Radiance& radiance, int margin = 2) {
  double se = 0;
  std::int64_t n = 0;
  for (const io::Frame& f : split.frames) {
    if (f.image.width == 0 || (!f.environment_only && f.mask.width == 0)) continue;
    const io::Image pred = environment_view_with(f, radiance);
    const io::Mask bg = background_mask(f, margin);
    const auto a = io::tone_map(pred), b = io::tone_map(f.image);
    for (int y = 0; y < f.image.height; ++y)
      for (int x = 0; x < f.image.width; ++x) {
        if (!bg.at(x, y)) continue;
        for (int c = 0; c < 3; ++c) {
          const std::size_t i = (std::size_t(y) * f.image.width + x) * 3 + c;
          const double d = double(a[i]) - double(b[i]);
          se += d * d;
        }
        n += 3;
      }
  }
  return n ? metrics::detail::psnr_from_mse(se / double(n)) : 0.0;
}

inline double background_psnr(const io::Split& split, const scene::EnvMap& env, int margin = 2) {
  return background_psnr_with(split, distant_radiance(env), margin);
}

}  // namespace difftrans::render
