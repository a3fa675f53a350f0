// The colour terms of stage 2, per traced ray: ĉ the rendered radiance, c the
// photograph's pixel (linear RGB). Each returns the value and dvalue/dĉ; the
// caller weights, averages over the batch and hands the adjoint to the tracer.
//
//   colour, plain L2:    Σ_ch (ĉ − c)²                      d/dĉ = 2 (ĉ − c)
//   colour, relative L2: Σ_ch (ĉ − c)² / (sg(ĉ)² + 0.01)     d/dĉ = 2 (ĉ − c) / (sg(ĉ)² + 0.01)
//       sg(): held constant; the HDR-robust loss of RawNeRF (Mildenhall et
//       al. 2022). On a glass sphere (tests/pipeline/materials) plain L2 found
//       IoR 1.4477 for 1.45 and relative L2 1.4378, biased by the one-ray
//       noise in its denominator, so plain L2 is the pipeline's default;
//   colour, log L2:      Σ_ch (log(1 + ĉ) − log(1 + c))²      d/dĉ = 2 (log(1 + ĉ) − log(1 + c)) / (1 + ĉ)
//       bounded per ray in an HDR scene: a ray on the sun (radiance in the
//       thousands) weighs like a ray on a bright sky, not 10⁷ times more, and
//       its derivative is damped by 1 / (1 + ĉ). Negative radiance (never
//       from the tracer) is clamped to 0 for this variant;
//   tone:                (1 − cos(ĉ, c))², cos = ĉ·c / (|ĉ||c|)
//       d cos/dĉ = c / (|ĉ||c|) − cos ĉ / |ĉ|²: the hue that absorption sets
//       (DiffTrans' colour-direction term); 0 with no gradient when either
//       vector is below 1e-6 in length.
#pragma once

#include <cmath>

#include "difftrans/ad/glm.hpp"

namespace difftrans::losses {

enum class ColourLoss : int { l2, relative_l2, log_l2 };

struct RayColourLoss {
  double colour = 0.0, tone = 0.0;
  Vec3f dcolour{0.0f}, dtone{0.0f};  // d/dĉ
};

// The residual a colour loss squares, per channel: f(ĉ) − f(c) with f the
// identity (l2; relative_l2 too, whose denominator only ray_colour_loss
// applies) or log(1 + max(0, x)) (log_l2), and its derivative f'(ĉ). Stage
// 2's pixel pairs multiply two samples' residuals instead of squaring one.
struct ColourResidual {
  float value = 0.0f, derivative = 0.0f;
};

inline ColourResidual colour_residual(float rendered, float target, ColourLoss kind) {
  if (kind != ColourLoss::log_l2) return {rendered - target, 1.0f};
  const double r = rendered > 0.0f ? double(rendered) : 0.0;
  const double t = target > 0.0f ? double(target) : 0.0;
  return {float(std::log1p(r) - std::log1p(t)), rendered > 0.0f ? float(1.0 / (1.0 + r)) : 0.0f};
}

inline RayColourLoss ray_colour_loss(const Vec3f& rendered, const Vec3f& target, ColourLoss kind, bool with_tone) {
  RayColourLoss out;
  for (int ch = 0; ch < 3; ++ch) {
    if (kind == ColourLoss::log_l2) {
      const double r = rendered[ch] > 0.0f ? double(rendered[ch]) : 0.0;
      const double t = target[ch] > 0.0f ? double(target[ch]) : 0.0;
      const double d = std::log1p(r) - std::log1p(t);
      out.colour += d * d;
      out.dcolour[ch] = rendered[ch] > 0.0f ? float(2.0 * d / (1.0 + r)) : 0.0f;
      continue;
    }
    const float denom = kind == ColourLoss::relative_l2 ? rendered[ch] * rendered[ch] + 0.01f : 1.0f;
    const float d = rendered[ch] - target[ch];
    out.colour += double(d) * d / denom;
    out.dcolour[ch] = 2.0f * d / denom;
  }
  const float nl = glm::length(rendered), nc = glm::length(target);
  if (with_tone && nl > 1e-6f && nc > 1e-6f) {
    const float cosv = glm::dot(rendered, target) / (nl * nc), one = 1.0f - cosv;
    out.tone = double(one) * one;
    const Vec3f dcos = target / (nl * nc) - cosv * rendered / (nl * nl);
    out.dtone = -2.0f * one * dcos;
  }
  return out;
}

}  // namespace difftrans::losses
