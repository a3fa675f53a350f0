// Choosing between two models of the same data by held-out error: each
// candidate is fitted without some of the views, and both are scored on the
// same held-out pixels, so the comparison is paired: the per-pixel
// difference's mean and standard error. The richer candidate (more
// parameters, more time) is kept only when it wins measurably: by more than
// a number of standard errors AND by more than a fraction of the simpler
// one's error. Used for stage 2's absorption (absorption_model.hpp) and for
// the environment (environment.hpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace difftrans::pipeline {

// Two candidates' per-pixel held-out losses (the same pixels in the same
// order; NaN marks a pixel left out, in either): the mean of each over the
// pixels both kept, the mean of simpler − richer and its standard error.
struct PairedComparison {
  double simpler = 0.0, richer = 0.0;
  double gain = 0.0, standard_error = 0.0;  // mean (simpler − richer), and its standard error
  std::size_t pixels = 0;
  // the richer candidate lowers the loss by more than `sigmas` standard
  // errors and by more than `min_gain` of the simpler one's loss
  bool richer_wins(double sigmas, double min_gain) const {
    return pixels > 1 && gain > sigmas * standard_error && gain > min_gain * simpler;
  }
  // beyond `sigmas` standard errors, but short of `min_gain`: a real gain
  // the rule still turns down (Stage2Config::finer_grid_for_vertices)
  bool short_of_min_gain(double sigmas, double min_gain) const {
    return richer_wins(sigmas, 0.0) && !richer_wins(sigmas, min_gain);
  }
  // the gain and its standard error as fractions of the simpler one's loss (0 where that is not positive)
  double relative_gain() const { return simpler > 0.0 ? gain / simpler : 0.0; }
  double relative_standard_error() const { return simpler > 0.0 ? standard_error / simpler : 0.0; }
};

inline PairedComparison compare_paired(const std::vector<double>& simpler, const std::vector<double>& richer) {
  PairedComparison c;
  const std::size_t n = std::min(simpler.size(), richer.size());
  double sum_d = 0.0, sum_d2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(simpler[i]) || !std::isfinite(richer[i])) continue;
    const double d = simpler[i] - richer[i];
    c.simpler += simpler[i];
    c.richer += richer[i];
    sum_d += d;
    sum_d2 += d * d;
    ++c.pixels;
  }
  if (c.pixels == 0) return c;
  const double m = double(c.pixels);
  c.simpler /= m;
  c.richer /= m;
  c.gain = sum_d / m;
  const double var = c.pixels > 1 ? std::max(0.0, (sum_d2 - m * c.gain * c.gain) / (m - 1.0)) : 0.0;
  c.standard_error = std::sqrt(var / m);
  return c;
}

// The mean of the finite entries (NaN: none finite).
inline double mean_finite(const std::vector<double>& v) {
  double sum = 0.0;
  std::size_t n = 0;
  for (double x : v)
    if (std::isfinite(x)) sum += x, ++n;
  return n ? sum / double(n) : std::numeric_limits<double>::quiet_NaN();
}

// Two candidates that share a parameter each fitted its own way (stage 2's
// none and homogeneous absorption, the IoR): each is scored at its own value
// and at the other's, and judged by the lower mean. The shared parameter's
// fitting noise is no merit of either model; judged at their own values only,
// a clear object took a faint tint because its homogeneous fit had happened
// to land nearer the true IoR. True: judge this candidate by `at_other`
// (also when no loss at its own value is finite and some at the other's are).
inline bool judged_at_other(const std::vector<double>& at_own, const std::vector<double>& at_other) {
  const double own = mean_finite(at_own), other = mean_finite(at_other);
  return std::isfinite(other) && (!std::isfinite(own) || other < own);
}

}  // namespace difftrans::pipeline
