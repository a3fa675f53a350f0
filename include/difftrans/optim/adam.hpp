// Adam and AdamUniform (Nicolet et al. 2021) over flat float arrays, and
// learning-rate schedules as plain functions of the iteration.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace difftrans::optim {

// ------------------------------------------------------------ schedules

// lr0 · 10^(−decay · i): the paper's lr 0.01 · 10^(−0.0002 i) is
// exponential_lr(0.01f, i, 0.0002f).
inline float exponential_lr(float lr0, int iteration, float decay = 0.0002f) {
  return float(double(lr0) * std::pow(10.0, -double(decay) * double(iteration)));
}

// `before` for iterations < switch_at, `after` from then on (the IoR's
// 1e-4 then 1e-3).
inline float step_lr(float before, float after, int switch_at, int iteration) {
  return iteration < switch_at ? before : after;
}

// Linear ramp from 0 to lr over the first `warmup` iterations, then lr.
inline float warmup_lr(float lr, int warmup, int iteration) {
  if (warmup <= 0 || iteration >= warmup) return lr;
  return lr * float(iteration + 1) / float(warmup);
}

// ------------------------------------------------------------ optimizers

struct AdamOptions {
  float lr = 1e-3f;
  float beta1 = 0.9f;
  float beta2 = 0.999f;
  float eps = 1e-8f;
};

// What an Adam-type optimizer remembers between steps: the moments and the
// step count. state() / restore() carry it through a checkpoint.
struct AdamState {
  std::vector<float> g1, g2;
  int steps = 0;
};

namespace detail {

// The moment state both variants share: g1, g2 and the step count.
class AdamMoments {
 public:
  explicit AdamMoments(std::size_t size = 0, AdamOptions options = {}) : options_(options) { reset(size); }

  // Forgets the moments and the step count (e.g. after remeshing changes the
  // number of parameters).
  void reset(std::size_t size) {
    g1_.assign(size, 0.0f);
    g2_.assign(size, 0.0f);
    steps_ = 0;
  }

  std::size_t size() const { return g1_.size(); }
  int steps() const { return steps_; }
  const AdamOptions& options() const { return options_; }
  AdamOptions& options() { return options_; }
  const std::vector<float>& first_moment() const { return g1_; }
  const std::vector<float>& second_moment() const { return g2_; }

  AdamState state() const { return {g1_, g2_, steps_}; }

  // How the gradient behaves, from the moments (bias-corrected):
  // agreement = |m̂1|² / Σ m̂2, the share of the gradient's energy that its
  // running mean keeps: 1 for a gradient that repeats step after step, about
  // (1 − β1) / (1 + β1) (0.053 at β1 0.9) for one that is pure noise;
  // peak = max √m̂2 / √(mean m̂2), how far the largest entry stands above the
  // typical one (1 when all are alike; AdamUniform's step scales with its
  // inverse). Both 0 before the first step or for a zero gradient.
  struct Summary {
    double agreement = 0.0, peak = 0.0;
  };
  Summary summary() const {
    Summary s;
    double m1 = 0.0, m2 = 0.0, top = 0.0;
    for (std::size_t i = 0; i < g1_.size(); ++i) {
      m1 += double(g1_[i]) * double(g1_[i]);
      m2 += double(g2_[i]);
      top = std::max(top, double(g2_[i]));
    }
    if (steps_ == 0 || !(m2 > 0.0)) return s;
    const double c1 = 1.0 - std::pow(double(options_.beta1), double(steps_));
    const double c2 = 1.0 - std::pow(double(options_.beta2), double(steps_));
    s.agreement = (m1 / (c1 * c1)) / (m2 / c2);
    s.peak = std::sqrt(top / (m2 / double(g2_.size())));
    return s;
  }
  // Continues from a saved state (its size becomes the optimizer's size).
  void restore(const AdamState& state) {
    if (state.g1.size() != state.g2.size() || state.steps < 0)
      throw std::invalid_argument("Adam::restore: moments of different sizes or a negative step count");
    g1_ = state.g1;
    g2_ = state.g2;
    steps_ = state.steps;
  }

 protected:
  // Updates g1, g2 with grad and returns the bias corrections 1 − β^t.
  void accumulate(const float* grad, double& c1, double& c2) {
    ++steps_;
    const float b1 = options_.beta1, b2 = options_.beta2;
    for (std::size_t i = 0; i < g1_.size(); ++i) {
      const float g = grad[i];
      g1_[i] = b1 * g1_[i] + (1.0f - b1) * g;
      g2_[i] = b2 * g2_[i] + (1.0f - b2) * g * g;
    }
    c1 = 1.0 - std::pow(double(b1), double(steps_));
    c2 = 1.0 - std::pow(double(b2), double(steps_));
  }

  AdamOptions options_;
  std::vector<float> g1_, g2_;
  int steps_ = 0;
};

}  // namespace detail

// Adam (Kingma & Ba): per entry p ← p − lr · m̂1 / (√m̂2 + ε) with the
// bias-corrected moments m̂1 = g1 / (1 − β1^t), m̂2 = g2 / (1 − β2^t).
class Adam : public detail::AdamMoments {
 public:
  explicit Adam(std::size_t size = 0, AdamOptions options = {}) : AdamMoments(size, options) {}

  // One step on params[0 .. size) with the gradient grad, at learning rate lr
  // (a schedule's value), or options().lr.
  void step(float* params, const float* grad, float lr) {
    double c1, c2;
    accumulate(grad, c1, c2);
    const double eps = options_.eps;
    for (std::size_t i = 0; i < g1_.size(); ++i) {
      const double m1 = double(g1_[i]) / c1, m2 = double(g2_[i]) / c2;
      params[i] = float(double(params[i]) - double(lr) * m1 / (std::sqrt(m2) + eps));
    }
  }
  void step(float* params, const float* grad) { step(params, grad, options_.lr); }
  void step(std::vector<float>& params, const std::vector<float>& grad, float lr) {
    check_sizes(params.size(), grad.size());
    step(params.data(), grad.data(), lr);
  }
  void step(std::vector<float>& params, const std::vector<float>& grad) { step(params, grad, options_.lr); }

 private:
  void check_sizes(std::size_t p, std::size_t g) const {
    if (p != size() || g != size()) throw std::invalid_argument("Adam::step: size mismatch");
  }
};

// AdamUniform (Nicolet et al. 2021): the moments as in Adam, but one step
// scale for the whole tensor: p ← p − lr · m̂1 / (ε + max_i √m̂2_i). The step
// direction is then the (momentum-averaged) gradient itself, which keeps the
// smoothness the large-steps parameterization gives it.
class AdamUniform : public detail::AdamMoments {
 public:
  explicit AdamUniform(std::size_t size = 0, AdamOptions options = {}) : AdamMoments(size, options) {}

  void step(float* params, const float* grad, float lr) {
    double c1, c2;
    accumulate(grad, c1, c2);
    float g2max = 0.0f;
    for (float v : g2_) g2max = std::max(g2max, v);
    last_scale_ = double(lr) / (double(options_.eps) + std::sqrt(double(g2max) / c2));
    for (std::size_t i = 0; i < g1_.size(); ++i)
      params[i] = float(double(params[i]) - last_scale_ * double(g1_[i]) / c1);
  }
  void step(float* params, const float* grad) { step(params, grad, options_.lr); }
  void step(std::vector<float>& params, const std::vector<float>& grad, float lr) {
    if (params.size() != size() || grad.size() != size())
      throw std::invalid_argument("AdamUniform::step: size mismatch");
    step(params.data(), grad.data(), lr);
  }
  void step(std::vector<float>& params, const std::vector<float>& grad) { step(params, grad, options_.lr); }

  // The factor of the last step: params changed by −last_scale() · m̂1.
  double last_scale() const { return last_scale_; }

 private:
  double last_scale_ = 0.0;
};

}  // namespace difftrans::optim
