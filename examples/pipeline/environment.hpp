// The environment stage of the pipeline: its configuration, and the
// background pixels of a scene directory as environment observations (the ray
// through each pixel centre that the object's mask leaves out, minus a margin
// around the mask, with the pixel's radiance) and the comparison of a fitted
// environment with held-out background pixels. The environment is a distant
// map (EnvMap, scene/envmap_fit.hpp) or any radiance(origin, direction) (a
// near field, scene/radiance_field_fit.hpp).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "difftrans/core/parallel.hpp"
#include "difftrans/io/dataset.hpp"
#include "difftrans/metrics/image.hpp"
#include "difftrans/render/views.hpp"
#include "pipeline/config.hpp"
#include "difftrans/scene/envmap_fit.hpp"

namespace difftrans::pipeline {

using render::camera_of;

enum class EnvironmentModel : int { automatic, distant, near };
inline const std::array<const char*, 3>& enum_names(EnvironmentModel) {
  static const std::array<const char*, 3> names{"auto", "distant", "near"};
  return names;
}

struct EnvironmentConfig {
  EnvironmentModel model = EnvironmentModel::automatic;  // auto: chosen from the background pixels
  int margin = 2;                 // pixels around the mask left out
  // distant: equirectangular map
  int env_width = 0;              // 0: from the images' angular resolution (capped at env_max_width)
  int env_max_width = 512;
  double smoothness = 1e-3;
  // near: radiance field (scene/radiance_field_fit.hpp)
  std::string field_resolutions = "32,64";      // grid vertices per axis, one level each (a 128 level overfits 50 views)
  std::string field_iterations = "300,300";     // per level
  int field_batch = 4096;
  float field_extent = 1.4f;      // box half-size / the farthest training camera's distance from the object's centre
  float field_lr = 0.1f;
  float field_tv = 1e-9f;         // smoothness prior weight (density and colour)
  float field_sparsity = 1e-6f;   // density sparsity prior weight
  std::uint64_t field_seed = 1;
  // auto: both models are fitted without every choice_holdout-th training
  // frame and scored on its background pixels (model_choice.hpp); the near
  // field is kept when it lowers the held-out error by more than two
  // standard errors and choice_min_gain of it; scene.json's entry decides
  // when neither model is measurably better.
  int choice_holdout = 5;
  float choice_min_gain = 0.02f;
  // The near field fitted for the choice alone: iterations per level of
  // field_resolutions (a third of the fit's). On a room of 40 views of 24²
  // the near field's held-out error was 19 / 43 / 50 % below the distant
  // map's after 100 / 200 / 600 iterations (16³, 32³), and under a far map
  // 517 / 225 / 402 % above: the decision does not need the whole fit.
  std::string choice_field_iterations = "100,100";

  // The one list of settings (pipeline/config.hpp): options, record, log.
  template <class Self, class Visit>
  static void fields(Self& c, Visit&& v) {
    v(Field{"model_requested", "--env-model",
            "Environment model: auto (both fitted without every --env-holdout-th view and compared on its "
            "background; scene.json's \"environment\" decides a tie), distant (equirectangular map) or near "
            "(radiance field)"},
      c.model);
    v(Field{"margin", "--margin", "Pixels around the mask left out of the environment fit", 0, 1000}, c.margin);
    v(Field{"env_width", "--env-width", "Environment map (or panorama) width (0: from the images' angular resolution)",
            0, 16384},
      c.env_width);
    v(Field{"env_max_width", "--env-max-width", "Largest automatic map width", 16, 16384}, c.env_max_width);
    v(Field{"env_smoothness", "--env-smoothness", "Weight of the distant map's smoothness prior", 0, 1e6}, c.smoothness);
    v(Field{"field_resolutions", "--field-resolutions",
            "Radiance field: grid vertices per axis of each coarse-to-fine level"},
      c.field_resolutions);
    v(Field{"field_iterations", "--field-iterations", "Radiance field: iterations per level (one count or one per level)"},
      c.field_iterations);
    v(Field{"field_batch", "--field-batch", "Radiance field: rays per iteration", 1, 1 << 24}, c.field_batch);
    v(Field{"field_extent", "--field-extent",
            "Radiance field: half-size of its cube / distance of the farthest camera from the object's centre", 1, 100},
      c.field_extent);
    v(Field{"field_lr", "--field-lr", "Radiance field: Adam learning rate (decays tenfold over the fit)", 1e-6, 10},
      c.field_lr);
    v(Field{"field_tv", "--field-tv", "Radiance field: weight of the smoothness prior on the grid", 0, 1e3}, c.field_tv);
    v(Field{"field_sparsity", "--field-sparsity", "Radiance field: weight of the density sparsity prior", 0, 1e3},
      c.field_sparsity);
    v(Field{"field_seed", "--field-seed", "Radiance field: seed of the ray batches"}, c.field_seed);
    v(Field{"choice_holdout", "--env-holdout", "auto: every Nth training view is held out to compare the models", 2,
            1e6},
      c.choice_holdout);
    v(Field{"choice_min_gain", "--env-min-gain",
            "auto: the near field must lower the held-out error by this fraction (and by 2 standard errors)", 0, 1},
      c.choice_min_gain);
    v(Field{"choice_field_iterations", "--env-choice-iterations",
            "auto: iterations per level of the near field fitted for the choice (one count or one per level)"},
      c.choice_field_iterations);
  }
};

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

// Per texel of a width x height map, 1 where a bilinear lookup of some
// observation's direction gives it weight: the directions the background
// pixels saw. The others are the environment fit's prior (its harmonic
// fill), which object rays may still see through the object.
inline std::vector<std::uint8_t> seen_texels(const std::vector<scene::EnvObservation>& obs, int width, int height) {
  std::vector<std::uint8_t> seen(std::size_t(std::max(width, 0)) * std::size_t(std::max(height, 0)), 0);
  if (seen.empty()) return seen;
  for (const scene::EnvObservation& ob : obs) {
    const scene::Footprint<float> f = scene::bilinear_footprint(width, height, scene::direction_to_uv(ob.direction));
    if (!f.valid) continue;
    for (int k = 0; k < 4; ++k)
      if (f.weight[k] > 0.0f) seen[std::size_t(f.texel[k])] = 1;
  }
  return seen;
}

// The share of the sphere's solid angle that the marked texels of a
// width x height equirectangular map cover (a texel row at polar angle θ
// spans sin θ of it).
inline double seen_solid_angle_fraction(const std::vector<std::uint8_t>& seen, int width, int height) {
  double marked = 0.0, all = 0.0;
  for (int row = 0; row < height; ++row) {
    const double a = std::sin(3.14159265358979323846 * (row + 0.5) / height);
    for (int col = 0; col < width; ++col) {
      all += a;
      if (seen[std::size_t(row) * std::size_t(width) + std::size_t(col)]) marked += a;
    }
  }
  return all > 0.0 ? marked / all : 0.0;
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

// Per background pixel of a frame (at least `margin` pixels from the mask),
// the squared error of the environment's radiance against the image, tone
// mapped (docs/metrics.md) and summed over RGB, appended to `errors` row by
// row; radiance(origin, direction) as for environment_view_with. With
// `directions`, each pixel's ray direction is appended there too.
template <class Radiance>
void background_errors_with(const io::Frame& f, const Radiance& radiance, int margin, std::vector<double>& errors,
                            std::vector<Vec3f>* directions = nullptr) {
  if (f.image.width == 0 || (!f.environment_only && f.mask.width == 0)) return;
  const io::Image pred = environment_view_with(f, radiance);
  const io::Mask bg = background_mask(f, margin);
  const scene::Camera cam = camera_of(f);
  const auto a = io::tone_map(pred), b = io::tone_map(f.image);
  for (int y = 0; y < f.image.height; ++y)
    for (int x = 0; x < f.image.width; ++x) {
      if (!bg.at(x, y)) continue;
      double se = 0.0;
      for (int c = 0; c < 3; ++c) {
        const std::size_t i = (std::size_t(y) * f.image.width + x) * 3 + c;
        const double d = double(a[i]) - double(b[i]);
        se += d * d;
      }
      errors.push_back(se);
      if (directions) directions->push_back(cam.generate_ray(x, y).direction);
    }
}

// PSNR (docs/metrics.md) of the environment against the background
// pixels of held-out frames, over all their background pixels together.
template <class Radiance>
double background_psnr_with(const io::Split& split, const Radiance& radiance, int margin = 2) {
  std::vector<double> errors;
  for (const io::Frame& f : split.frames) background_errors_with(f, radiance, margin, errors);
  double se = 0.0;
  for (double e : errors) se += e;
  return errors.empty() ? 0.0 : metrics::detail::psnr_from_mse(se / (3.0 * double(errors.size())));
}

inline double background_psnr(const io::Split& split, const scene::EnvMap& env, int margin = 2) {
  return background_psnr_with(split, distant_radiance(env), margin);
}

}  // namespace difftrans::pipeline
