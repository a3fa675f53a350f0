// The regularizers of a 3D absorption grid (σ = softplus(p) at its vertices,
// p the raw parameters; scene/absorption.hpp), as in DiffTrans' stage 2:
//   smoothness (TV):  mean over neighbouring vertex pairs (all three axes) and
//                     channels of |σ(a) − σ(b)|, subgradient sign(σ(a) − σ(b));
//   volume:           mean over vertices and channels of σ², gradient 2σ;
// both chained through dσ/dp = sigmoid(p).
#pragma once

#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/math.hpp"

namespace difftrans::losses {

// Mean |σ(a) − σ(b)| over neighbouring grid vertices (all three axes) and
// mean σ² over vertices and channels; gradients w.r.t. the raw parameters
// (σ = softplus(p)) added to `grad` times the weights. Returns {tv, volume}.
inline std::pair<double, double> absorption_regularizers(const std::vector<float>& raw, const Vec3i& res, float w_tv,
                                                         float w_volume, std::vector<float>& grad) {
  const std::size_t n = std::size_t(res.x) * std::size_t(res.y) * std::size_t(res.z);
  std::vector<float> sigma(raw.size()), dsig(raw.size());
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const float p = raw[i];
    sigma[i] = ad::softplus(p);
    dsig[i] = ad::sigmoid(p);
  }
  double tv = 0.0, vol = 0.0;
  std::size_t pairs = 0;
  const auto idx = [&](int i, int j, int k) { return ((std::size_t(k) * std::size_t(res.y) + std::size_t(j)) * std::size_t(res.x) + std::size_t(i)) * 3; };
  for (int k = 0; k < res.z; ++k)
    for (int j = 0; j < res.y; ++j)
      for (int i = 0; i < res.x; ++i) {
        const int nb[3][3] = {{i + 1, j, k}, {i, j + 1, k}, {i, j, k + 1}};
        for (const auto& q : nb)
          if (q[0] < res.x && q[1] < res.y && q[2] < res.z) ++pairs;
      }
  const float tv_scale = pairs ? w_tv / float(3 * pairs) : 0.0f, vol_scale = w_volume / float(3 * n);
  for (int k = 0; k < res.z; ++k)
    for (int j = 0; j < res.y; ++j)
      for (int i = 0; i < res.x; ++i) {
        const std::size_t a = idx(i, j, k);
        for (int c = 0; c < 3; ++c) {
          vol += double(sigma[a + c]) * sigma[a + c];
          grad[a + c] += vol_scale * 2.0f * sigma[a + c] * dsig[a + c];
        }
        const int nb[3][3] = {{i + 1, j, k}, {i, j + 1, k}, {i, j, k + 1}};
        for (const auto& q : nb) {
          if (q[0] >= res.x || q[1] >= res.y || q[2] >= res.z) continue;
          const std::size_t b = idx(q[0], q[1], q[2]);
          for (int c = 0; c < 3; ++c) {
            const float d = sigma[a + c] - sigma[b + c];
            tv += std::abs(d);
            const float s = d > 0.0f ? 1.0f : (d < 0.0f ? -1.0f : 0.0f);
            grad[a + c] += tv_scale * s * dsig[a + c];
            grad[b + c] -= tv_scale * s * dsig[b + c];
          }
        }
      }
  return {pairs ? tv / double(3 * pairs) : 0.0, vol / double(3 * n)};
}

}  // namespace difftrans::losses
