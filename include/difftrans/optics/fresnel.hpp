// Fresnel reflectance of a smooth dielectric interface (unpolarized light),
// generic over the scalar type. Conventions (pbrt, Mitsuba): cos_theta_i is
// measured against the surface normal, eta = IoR of the side the light enters
// over the IoR of the side it leaves (the side the normal points away from);
// cos_theta_i < 0 means the light arrives from the back and eta is inverted.
#pragma once

#include "difftrans/ad/math.hpp"

namespace difftrans::optics {

template <class S>
struct FresnelResult {
  S R;            // unpolarized reflectance in [0, 1]; 1 on total internal reflection
  S cos_theta_t;  // cosine of the transmitted direction, signed opposite to cos_theta_i; 0 on TIR
  S eta_it;       // relative IoR the light actually crosses (eta, or 1/eta from the back)
  S eta_ti;       // 1 / eta_it
  bool tir;       // total internal reflection: no transmitted ray
};

namespace detail {

// Snell's law: |cos θ_t| from |cos θ_i| and the relative IoR. The only place
// the refraction cosine is computed; fresnel_dielectric and refract share it.
template <class S>
struct Snell {
  S cos_i;  // |cos θ_i|, clamped to [0, 1]
  S cos_t;  // |cos θ_t|, 0 on TIR
  S eta_it, eta_ti;
  bool tir;
  bool flipped;  // the light arrived from the back side
};

template <class S>
DT_HOST_DEVICE DT_FORCEINLINE Snell<S> snell(const S& cos_theta_i, const S& eta) {
  Snell<S> s;
  const S c = clamp(cos_theta_i, S(-1), S(1));
  s.flipped = c < 0;
  s.cos_i = s.flipped ? -c : c;
  s.eta_it = s.flipped ? S(1) / eta : eta;
  s.eta_ti = s.flipped ? eta : S(1) / eta;
  // cos²θ_t = 1 − η_ti² sin²θ_i, arranged as η_ti² cos²θ_i + (1 − η_ti²) so
  // that it is exact for η = 1 and has no cancellation near grazing incidence.
  const S eta2 = s.eta_ti * s.eta_ti;
  const S cos2_t = eta2 * (s.cos_i * s.cos_i) + (S(1) - eta2);
  s.tir = cos2_t < 0;
  // safe_sqrt: finite derivative as cos²θ_t → 0 (the TIR boundary)
  s.cos_t = s.tir ? S(0) : safe_sqrt(cos2_t);
  return s;
}

}  // namespace detail

template <class A, class B>
DT_HOST_DEVICE FresnelResult<ad::promote_t<A, B>> fresnel_dielectric(const A& cos_theta_i, const B& eta) {
  using S = ad::promote_t<A, B>;
  const detail::Snell<S> s = detail::snell(S(cos_theta_i), S(eta));
  FresnelResult<S> f;
  f.eta_it = s.eta_it;
  f.eta_ti = s.eta_ti;
  f.tir = s.tir;
  f.cos_theta_t = s.flipped ? s.cos_t : -s.cos_t;
  if (s.tir) {
    f.R = S(1);
  } else if (s.eta_it == 1) {
    f.R = S(0);  // index matched: no interface (dR/dη = 0 here, as R ∝ (η − 1)²)
  } else {
    const S ec_i = s.eta_it * s.cos_i, ec_t = s.eta_it * s.cos_t;
    const S r_parallel = (ec_i - s.cos_t) / (ec_i + s.cos_t);
    const S r_perpendicular = (s.cos_i - ec_t) / (s.cos_i + ec_t);
    f.R = S(0.5) * (square(r_parallel) + square(r_perpendicular));
  }
  return f;
}

}  // namespace difftrans::optics
