// Adaptive sampling of a camera image, in rounds: each round traces n × n
// stratified samples in every pixel still active, shifted within their strata
// by the round's offset (round 0: the stratum centres; then the R2
// low-discrepancy sequence), so every round is an estimate of the pixel on
// its own. The spread of a pixel's round means measures the error of their
// mean; a pixel stops when two standard errors move its 8-bit tone-mapped
// value (docs/conventions.md: clamp to [0, 1], sRGB) by no more than
// `tolerance` levels in every channel. Rounds double from min_rounds to
// max_rounds. Plain and saturated pixels stop early; edges, textures seen
// through the object and glints get the samples. A glint that none of a
// pixel's first rounds sees is not found (as with uniform sampling at that
// rate), and a stopping rule read from the samples leaves a small bias.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

#include "difftrans/core/parallel.hpp"
#include "difftrans/io/image.hpp"
#include "difftrans/render/passes.hpp"

namespace difftrans::render {

struct AdaptiveOptions {
  int per_axis = 2;        // n: each round's n × n samples per pixel
  int min_rounds = 2;      // at least 2: the spread of the rounds' means is the error measure
  int max_rounds = 64;     // no pixel gets more than max_rounds · n² samples
  float tolerance = 2.0f;  // 8-bit levels the tone-mapped value may still move by (two standard errors)
};

struct AdaptiveStats {
  PassStats pass;                       // all rounds together
  std::vector<int> rounds;              // the round counts a pixel can stop at: min_rounds, doubled, ... max_rounds
  std::vector<std::int64_t> pixels_at;  // the pixels that stopped at each of them
  double mean_samples = 0.0;            // samples per pixel over the image
};

namespace detail {

// The sub-pixel offset of round r within each stratum: the centre, then the
// R2 sequence (additive recurrence with the plastic number).
inline Vec2f round_offset(int r) {
  const double a1 = 0.7548776662466927, a2 = 0.5698402909980532;
  return Vec2f(float(std::fmod(0.5 + a1 * r, 1.0)), float(std::fmod(0.5 + a2 * r, 1.0)));
}

// A pixel's round means, summed, and the tone-mapped stopping test.
struct PixelRounds {
  double sum[3] = {0, 0, 0}, sum_sq[3] = {0, 0, 0};
  int rounds = 0;
  void add(const Vec3<double>& round_mean) {
    for (int c = 0; c < 3; ++c) {
      sum[c] += round_mean[c];
      sum_sq[c] += round_mean[c] * round_mean[c];
    }
    ++rounds;
  }
  // true while two standard errors of the mean move the 8-bit value by more
  // than `tolerance` levels in some channel
  bool uncertain(float tolerance) const {
    if (rounds < 2) return true;
    for (int c = 0; c < 3; ++c) {
      const double mean = sum[c] / rounds;
      const double var = std::max(0.0, (sum_sq[c] - sum[c] * mean) / double(rounds - 1));
      const double half = 2.0 * std::sqrt(var / double(rounds));
      const int lo = io::tone_map_value(float(mean - half)), hi = io::tone_map_value(float(mean + half));
      if (float(hi - lo) > tolerance) return true;
    }
    return false;
  }
};

}  // namespace detail

// The round counts a pixel can stop at.
inline std::vector<int> adaptive_rounds(const AdaptiveOptions& a) {
  std::vector<int> r{std::max(2, a.min_rounds)};
  while (r.back() * 2 <= a.max_rounds) r.push_back(r.back() * 2);
  return r;
}

// Linear RGB radiance (width·height·3), the samples spent where the
// tone-mapped pixel is uncertain; `opt.samples_per_axis` is not used.
// Deterministic: the sample positions are fixed and each pixel's rounds are
// summed in order.
template <class Escape>
std::vector<float> render_image_adaptive_with(const HostScene& s, const scene::Camera& cam, const PassOptions& opt,
                                              const AdaptiveOptions& a, const Escape& escape,
                                              AdaptiveStats* stats = nullptr) {
  const std::vector<int> stops = adaptive_rounds(a);
  const int n = std::max(1, a.per_axis);
  const std::int64_t pixels = std::int64_t(cam.width) * cam.height;
  std::vector<detail::PixelRounds> acc(static_cast<std::size_t>(pixels));
  std::vector<std::int64_t> active(static_cast<std::size_t>(pixels));
  for (std::int64_t p = 0; p < pixels; ++p) active[std::size_t(p)] = p;
  std::vector<float> image(static_cast<std::size_t>(pixels) * 3, 0.0f);
  const SceneView view = s.view(false);
  const ad::ParamSet& params = s.params();
  AdaptiveStats st;
  st.rounds = stops;
  st.pixels_at.assign(stops.size(), 0);
  ThreadPool& pool = ThreadPool::global();
  const float inv = 1.0f / float(n);
  int done = 0;  // rounds every active pixel has
  for (std::size_t k = 0; k < stops.size() && !active.empty(); ++k) {
    const int first = done, last = stops[k];
    detail::StatsPerWorker per(pool.size());
    pool.parallel_for(std::int64_t(active.size()), 8, [&](std::int64_t b, std::int64_t e, int w) {
      ad::ParamReader<float> reader(&params);
      PassStats& ps = per.per[std::size_t(w)];
      for (std::int64_t q = b; q < e; ++q) {
        const std::int64_t pix = active[std::size_t(q)];
        const int x = int(pix % cam.width), y = int(pix / cam.width);
        for (int r = first; r < last; ++r) {
          const Vec2f o = detail::round_offset(r);
          Vec3<double> sum(0.0);
          for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
              const scene::Ray ray = cam.generate_ray(x, y, (float(i) + o.x) * inv, (float(j) + o.y) * inv);
              sum += Vec3<double>(trace<float>(view, s.accel(), reader, ray.origin, ray.direction, opt.trace,
                                               &ps.trace, escape));
              ++ps.rays;
            }
          acc[std::size_t(pix)].add(sum / double(n * n));
        }
      }
    });
    st.pass.add(per.total());
    done = last;
    const bool final_round = k + 1 == stops.size();
    std::vector<std::int64_t> next;
    for (const std::int64_t pix : active) {
      const detail::PixelRounds& p = acc[std::size_t(pix)];
      if (!final_round && p.uncertain(a.tolerance)) {
        next.push_back(pix);
        continue;
      }
      for (int c = 0; c < 3; ++c) image[std::size_t(pix) * 3 + std::size_t(c)] = float(p.sum[c] / double(p.rounds));
      ++st.pixels_at[k];
    }
    active.swap(next);
  }
  st.mean_samples = pixels ? double(st.pass.rays) / double(pixels) : 0.0;
  if (stats) *stats = std::move(st);
  return image;
}

inline std::vector<float> render_image_adaptive(const HostScene& s, const scene::Camera& cam, const PassOptions& opt,
                                                const AdaptiveOptions& a, AdaptiveStats* stats = nullptr) {
  std::vector<float> image;
  s.with_escape([&](const auto& escape) { image = render_image_adaptive_with(s, cam, opt, a, escape, stats); });
  return image;
}

// Sampling in levels of uniform grids. Every pixel is traced on the first
// level's n₀ × n₀ grid (pixel_sample's stratum centres: each level fully
// stratified, unlike the rounds above). A pixel whose samples so far spread —
// two standard errors of their mean (their sample variance over their count,
// an overestimate for stratified grids, used as a ranking) move its
// tone-mapped value by more than `tolerance` levels in some channel — is
// traced on the next level's grid as well, and so are the pixels within
// `dilate` of it (Chebyshev distance): a glint that one pixel's samples catch
// is often in its neighbours too, where none of theirs did. A pixel is the
// mean of all its samples; a sample that an earlier grid already traced (the
// same stratum centre: an odd ratio of the two grids, as 2 and 6) is not
// traced again. A first grid of 1 × 1 cannot show a spread: every pixel goes
// on. As with the rounds, a glint that no sample of a
// pixel or its neighbours sees is not found, and a stopping rule read from
// the samples leaves a small bias. Deterministic: the grids are fixed and
// every pixel is summed in order.
struct LevelOptions {
  std::vector<int> per_axis{2, 8};  // each level's n × n grid
  float tolerance = 32.0f;          // 8-bit levels; 255 or more marks no pixel (the first grid alone)
  int dilate = 1;                   // pixels around a spread one refined too
};

struct LevelStats {
  PassStats pass;                     // all levels
  std::vector<std::int64_t> traced;   // pixels traced at each level
  std::vector<std::int64_t> spread;   // pixels found spread after each level (but the last)
  double mean_samples = 0.0;          // per pixel over the image
};

template <class Escape>
std::vector<float> render_image_levels_with(const HostScene& s, const scene::Camera& cam, const PassOptions& opt,
                                            const LevelOptions& l, const Escape& escape,
                                            LevelStats* stats = nullptr) {
  const std::int64_t pixels = std::int64_t(cam.width) * cam.height;
  std::vector<detail::PixelRounds> acc(static_cast<std::size_t>(pixels));  // each sample a "round" of its own
  const SceneView view = s.view(false);
  const ad::ParamSet& params = s.params();
  ThreadPool& pool = ThreadPool::global();
  LevelStats st;
  // the pixels traced at the current level: every pixel at the first
  std::vector<std::int64_t> level_pixels(static_cast<std::size_t>(pixels));
  for (std::int64_t p = 0; p < pixels; ++p) level_pixels[std::size_t(p)] = p;
  const int d = std::max(0, l.dilate);
  if (l.per_axis.empty()) throw std::invalid_argument("render_image_levels: no grid given");
  // whether sample i of an n-grid's axis has the centre of a sample of an earlier grid g:
  // (i + 1/2) / n = (j + 1/2) / g, i.e. (2i + 1) g / n an odd integer
  const auto on_earlier_grid = [&](std::size_t level, int n, int i, int j) {
    for (std::size_t e = 0; e < level; ++e) {
      const std::int64_t g = std::max(1, l.per_axis[e]);
      const auto shared = [&](int k) {
        const std::int64_t x = (2 * std::int64_t(k) + 1) * g;
        return x % n == 0 && (x / n) % 2 == 1;
      };
      if (shared(i) && shared(j)) return true;
    }
    return false;
  };
  for (std::size_t level = 0; level < l.per_axis.size() && !level_pixels.empty(); ++level) {
    const int n = std::max(1, l.per_axis[level]);
    // the samples an earlier grid traced: the same for every pixel of the level
    std::vector<std::uint8_t> skip(static_cast<std::size_t>(n) * std::size_t(n));
    for (int k = 0; k < n * n; ++k) skip[std::size_t(k)] = on_earlier_grid(level, n, k % n, k / n);
    st.traced.push_back(std::int64_t(level_pixels.size()));
    detail::StatsPerWorker per(pool.size());
    pool.parallel_for(std::int64_t(level_pixels.size()), level == 0 ? 64 : 4, [&](std::int64_t b, std::int64_t e, int w) {
      ad::ParamReader<float> reader(&params);
      PassStats& ps = per.per[std::size_t(w)];
      for (std::int64_t q = b; q < e; ++q) {
        const std::int64_t pix = level_pixels[std::size_t(q)];
        for (int k = 0; k < n * n; ++k) {
          if (skip[std::size_t(k)]) continue;
          const scene::Ray r = pixel_sample(cam, n, pix, k);
          acc[std::size_t(pix)].add(
              Vec3<double>(trace<float>(view, s.accel(), reader, r.origin, r.direction, opt.trace, &ps.trace, escape)));
          ++ps.rays;
        }
      }
    });
    st.pass.add(per.total());
    if (level + 1 == l.per_axis.size()) break;
    // the next level: the spread pixels of this one and their neighbours
    std::vector<std::uint8_t> next(static_cast<std::size_t>(pixels), 0);
    std::int64_t spread = 0;
    for (const std::int64_t p : level_pixels) {
      if (!acc[std::size_t(p)].uncertain(l.tolerance)) continue;
      ++spread;
      const int x = int(p % cam.width), y = int(p / cam.width);
      for (int yy = std::max(0, y - d); yy <= std::min(cam.height - 1, y + d); ++yy)
        for (int xx = std::max(0, x - d); xx <= std::min(cam.width - 1, x + d); ++xx)
          next[std::size_t(yy) * std::size_t(cam.width) + std::size_t(xx)] = 1;
    }
    st.spread.push_back(spread);
    level_pixels.clear();
    for (std::int64_t p = 0; p < pixels; ++p)
      if (next[std::size_t(p)]) level_pixels.push_back(p);
  }
  std::vector<float> image(static_cast<std::size_t>(pixels) * 3, 0.0f);
  for (std::int64_t p = 0; p < pixels; ++p) {
    const detail::PixelRounds& a = acc[std::size_t(p)];
    for (int c = 0; c < 3; ++c) image[std::size_t(p) * 3 + std::size_t(c)] = a.rounds ? float(a.sum[c] / a.rounds) : 0.0f;
  }
  st.mean_samples = pixels ? double(st.pass.rays) / double(pixels) : 0.0;
  if (stats) *stats = std::move(st);
  return image;
}

inline std::vector<float> render_image_levels(const HostScene& s, const scene::Camera& cam, const PassOptions& opt,
                                              const LevelOptions& l, LevelStats* stats = nullptr) {
  std::vector<float> image;
  s.with_escape([&](const auto& escape) { image = render_image_levels_with(s, cam, opt, l, escape, stats); });
  return image;
}

}  // namespace difftrans::render
