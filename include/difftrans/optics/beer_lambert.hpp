// Beer–Lambert attenuation through a homogeneous absorbing medium:
// T = exp(−σ_a d) per colour channel. Underflows cleanly to 0 (value and
// derivative) for huge σ_a d. Spatially varying media are in scene/absorption.
#pragma once

#include "difftrans/ad/glm.hpp"

namespace difftrans::optics {

// Transmittance of one channel with absorption coefficient sigma over distance d.
template <class A, class B>
DT_HOST_DEVICE DT_FORCEINLINE ad::promote_t<A, B> transmittance(const A& sigma, const B& distance) {
  using S = ad::promote_t<A, B>;
  return exp(-(S(sigma) * S(distance)));  // d T = −T (d dσ + σ dd)
}

// RGB transmittance for an RGB absorption coefficient.
template <class S, class D>
DT_HOST_DEVICE DT_FORCEINLINE Vec3<ad::promote_t<S, D>> transmittance(const Vec3<S>& sigma, const D& distance) {
  using R = ad::promote_t<S, D>;
  return Vec3<R>(transmittance(sigma.x, distance), transmittance(sigma.y, distance),
                 transmittance(sigma.z, distance));
}

}  // namespace difftrans::optics
