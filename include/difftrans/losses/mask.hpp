// The silhouette loss of stage 1 and of stage 2's mask step.
//
// mask L1: (1/N) Σ_p |m(p) − m*(p)| over the N pixels of a view, m the
// anti-aliased coverage (render/silhouette.hpp), m* the photograph's mask
// (the paper's L_mask). Its subgradient sign(m − m*) / N is the adjoint that
// silhouette_backward turns into vertex gradients.
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

namespace difftrans::losses {

// Mean absolute difference between a mask and a target; when `adjoint` is
// given, writes the subgradient sign(mask - target) / N per pixel (0 where equal).
inline double mask_l1(const std::vector<float>& mask, const float* target, float* adjoint = nullptr) {
  const std::size_t n = mask.size();
  if (n == 0) return 0.0;
  double sum = 0.0;
  const float inv = 1.0f / float(n);
  for (std::size_t p = 0; p < n; ++p) {
    const float d = mask[p] - target[p];
    sum += std::fabs(double(d));
    if (adjoint) adjoint[p] = d > 0.0f ? inv : (d < 0.0f ? -inv : 0.0f);
  }
  return sum / double(n);
}

}  // namespace difftrans::losses
