// Index-of-refraction error of docs/metrics.md: |eta_predicted - eta_true|.
#pragma once

#include <cmath>

namespace difftrans::metrics {

inline double ior_error(double predicted, double truth) { return std::abs(predicted - truth); }

}  // namespace difftrans::metrics
