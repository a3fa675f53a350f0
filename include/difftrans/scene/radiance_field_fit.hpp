// Fits a near-field radiance field (scene/radiance_field.hpp) to background
// observations — rays (origin, direction) and the radiance seen along them —
// by volume rendering: coarse to fine (the grid resampled between levels),
// Adam on the raw values with random ray batches, a smoothness prior that
// keeps unseen regions finite and smooth, and empty cells pruned. Host only,
// on the thread pool.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <vector>

#include "difftrans/core/hash.hpp"
#include "difftrans/core/parallel.hpp"
#include "difftrans/optim/adam.hpp"
#include "difftrans/scene/radiance_field.hpp"

namespace difftrans::scene {

struct FieldFitOptions {
  std::vector<int> resolutions{32, 64};       // grid vertices per axis, one level each, coarse to fine
  std::vector<int> iterations{300, 300};      // per level (the last entry repeats if shorter)
  int batch = 4096;                            // rays per iteration
  float lr = 0.1f;                             // Adam, at the first iteration ...
  float lr_final = 0.01f;                      // ... decaying exponentially to this at the last
  // Data term: mean over the batch and channels of (g(C) − g(radiance))² with
  // g(x) = log(1 + x) (log_loss, so that a few very bright pixels — lights —
  // do not outweigh the rest and the field does not grow bright fog to match
  // their edges from every view) or g(x) = x.
  bool log_loss = true;
  // Smoothness prior on the raw values: Σ over grid edges of w (raw_a − raw_b)²,
  // against the data term mean over the batch of |C − radiance|².
  float smoothness_density = 1e-9f;
  float smoothness_colour = 1e-9f;
  // Sparsity prior: sparsity · Σ over grid vertices of σ, which empties the
  // space no ray needs filled (no fog in front of cameras the data cannot
  // tell apart from a wall).
  float sparsity = 1e-6f;
  float density_scale = 10.0f;
  float step_voxels = 0.5f;
  float init_density_raw = -10.0f;  // σ = density_scale · softplus(−10) ≈ 0.00045 per unit: nearly empty
  float init_colour_raw = 0.0f;    // c = softplus(0) ≈ 0.69
  int occupancy_every = 16;        // iterations between prunings of empty cells
  float occupancy_sigma = 1e-4f;   // cells below this σ (per unit length) everywhere are skipped
  std::uint64_t seed = 1;
};

struct FieldFitReport {
  int iterations = 0;
  double seconds = 0;
  double last_mse = 0;  // the data term over the last iteration's batch (see FieldFitOptions::log_loss)
  double occupied_fraction = 1;
};

// Obs: anything with Vec3f members origin, direction and radiance.
// progress(level, iteration, mse) is called every few dozen iterations.
template <class Obs, class Progress>
RadianceField fit_radiance_field(const std::vector<Obs>& obs, const Vec3f& lo, const Vec3f& hi,
                                 const FieldFitOptions& opt, FieldFitReport* report, Progress&& progress) {
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  if (obs.empty()) throw std::invalid_argument("fit_radiance_field: no observations");
  if (opt.resolutions.empty() || opt.iterations.empty())
    throw std::invalid_argument("fit_radiance_field: no levels (resolutions and iterations)");
  if (opt.batch < 1) throw std::invalid_argument("fit_radiance_field: batch must be >= 1");
  int total_iterations = 0;
  for (std::size_t l = 0; l < opt.resolutions.size(); ++l)
    total_iterations += std::max(0, opt.iterations[std::min(l, opt.iterations.size() - 1)]);

  ThreadPool& pool = ThreadPool::global();
  const int workers = pool.size();
  RadianceField field;
  field.density_scale = opt.density_scale;
  field.step_voxels = opt.step_voxels;
  optim::Adam bg_adam(3, optim::AdamOptions{opt.lr, 0.9f, 0.99f, 1e-8f});
  std::vector<float> bg_params(3, 0.0f);  // background radiance, clamped at 0
  std::vector<std::vector<float>> grads(static_cast<std::size_t>(workers));
  std::vector<std::vector<float>> bg_grads(std::size_t(workers), std::vector<float>(3, 0.0f));
  std::vector<std::vector<FieldSampleRecord<float>>> scratch(static_cast<std::size_t>(workers));
  std::vector<double> sq_error(std::size_t(workers), 0.0);
  std::vector<float> m1, m2;  // Adam moments of the grid
  const float beta1 = 0.9f, beta2 = 0.99f, eps = 1e-8f;
  const double decay = total_iterations > 1 ? std::log(double(opt.lr_final) / double(opt.lr)) / (total_iterations - 1) : 0.0;
  int global_it = 0;
  double last_mse = 0;

  for (std::size_t level = 0; level < opt.resolutions.size(); ++level) {
    const int n = opt.resolutions[level];
    if (n < 2) throw std::invalid_argument("fit_radiance_field: resolution " + std::to_string(n) + " < 2");
    if (level == 0) {
      RadianceField init(Vec3i(n), lo, hi, opt.init_density_raw, opt.init_colour_raw);
      init.density_scale = opt.density_scale;
      init.step_voxels = opt.step_voxels;
      field = std::move(init);
    } else {
      field = field.resampled(Vec3i(n));
    }
    const std::size_t size = field.values.size();
    for (auto& g : grads) g.assign(size, 0.0f);
    m1.assign(size, 0.0f);
    m2.assign(size, 0.0f);
    int adam_steps = 0;
    field.update_occupancy(opt.occupancy_sigma);
    const int iterations = std::max(0, opt.iterations[std::min(level, opt.iterations.size() - 1)]);
    for (int it = 0; it < iterations; ++it, ++global_it) {
      if (it > 0 && opt.occupancy_every > 0 && it % opt.occupancy_every == 0) field.update_occupancy(opt.occupancy_sigma);
      field.background = Vec3f(bg_params[0], bg_params[1], bg_params[2]);
      const RadianceFieldView view = field.view();
      const float inv_batch = 1.0f / float(opt.batch);
      const bool log_loss = opt.log_loss;
      std::fill(sq_error.begin(), sq_error.end(), 0.0);
      const std::uint64_t it_seed = splitmix64(opt.seed * 0x100000001B3ull + std::uint64_t(global_it));
      pool.parallel_for(opt.batch, 64, [&](std::int64_t b0, std::int64_t b1, int w) {
        float* grad = grads[std::size_t(w)].data();
        float* bg_grad = bg_grads[std::size_t(w)].data();
        auto& rec = scratch[std::size_t(w)];
        double se = 0;
        for (std::int64_t b = b0; b < b1; ++b) {
          const std::uint64_t h = splitmix64(it_seed + std::uint64_t(b));
          const Obs& o = obs[std::size_t(h % obs.size())];
          const float offset = float(unit_from_bits(splitmix64(h)));
          field_radiance_backward<float>(
              view, o.origin, o.direction, offset,
              [&](const Vec3f& C) {
                Vec3f adj;
                for (int ch = 0; ch < 3; ++ch) {
                  const float c = std::max(C[ch], 0.0f), y = std::max(o.radiance[ch], 0.0f);
                  const float r = log_loss ? std::log1p(c) - std::log1p(y) : c - y;
                  se += double(r) * double(r);
                  adj[ch] = 2.0f * inv_batch * r * (log_loss ? 1.0f / (1.0f + c) : 1.0f);
                }
                return adj;
              },
              grad, bg_grad, rec);
        }
        sq_error[std::size_t(w)] += se;
      });
      double se = 0;
      for (double s : sq_error) se += s;
      last_mse = se / (3.0 * opt.batch);
      if (opt.smoothness_density > 0.0f || opt.smoothness_colour > 0.0f)
        add_smoothness_gradient(field, opt.smoothness_density, opt.smoothness_colour, grads[0].data());
      // Adam on the grid (in parallel; the per-worker gradients are summed and cleared)
      const float lr = float(double(opt.lr) * std::exp(decay * global_it));
      ++adam_steps;
      const double c1 = 1.0 - std::pow(double(beta1), adam_steps), c2 = 1.0 - std::pow(double(beta2), adam_steps);
      const float step_scale = float(double(lr) / c1), inv_c2 = float(1.0 / c2);
      const float sparsity_grad = opt.sparsity * opt.density_scale;
      pool.parallel_for(std::int64_t(size), 1 << 14, [&](std::int64_t i0, std::int64_t i1, int) {
        for (std::int64_t i = i0; i < i1; ++i) {
          float g = 0.0f;
          for (auto& gw : grads) {
            g += gw[std::size_t(i)];
            gw[std::size_t(i)] = 0.0f;
          }
          if (i % 4 == 0 && sparsity_grad > 0.0f) g += sparsity_grad * sigmoid(field.values[std::size_t(i)]);  // dσ/draw
          float& a = m1[std::size_t(i)];
          float& b = m2[std::size_t(i)];
          a = beta1 * a + (1.0f - beta1) * g;
          b = beta2 * b + (1.0f - beta2) * g * g;
          field.values[std::size_t(i)] -= step_scale * a / (std::sqrt(b * inv_c2) + eps);
        }
      });
      // the background's three values: optim::Adam
      std::vector<float> g3(3, 0.0f);
      for (auto& bw : bg_grads)
        for (int ch = 0; ch < 3; ++ch) {
          g3[std::size_t(ch)] += bw[std::size_t(ch)];
          bw[std::size_t(ch)] = 0.0f;
        }
      bg_adam.step(bg_params, g3, lr);
      for (float& v : bg_params) v = std::max(v, 0.0f);
      if (it % 50 == 0 || it + 1 == iterations) progress(int(level), it, last_mse);
    }
  }
  field.background = Vec3f(bg_params[0], bg_params[1], bg_params[2]);
  field.update_occupancy(opt.occupancy_sigma);
  if (report) {
    report->iterations = global_it;
    report->seconds = std::chrono::duration<double>(clock::now() - start).count();
    report->last_mse = last_mse;
    std::size_t occ = 0;
    for (auto o : field.occupancy) occ += o;
    report->occupied_fraction = field.occupancy.empty() ? 1.0 : double(occ) / double(field.occupancy.size());
  }
  return field;
}

template <class Obs>
RadianceField fit_radiance_field(const std::vector<Obs>& obs, const Vec3f& lo, const Vec3f& hi,
                                 const FieldFitOptions& opt = {}, FieldFitReport* report = nullptr) {
  return fit_radiance_field(obs, lo, hi, opt, report, [](int, int, double) {});
}

}  // namespace difftrans::scene
