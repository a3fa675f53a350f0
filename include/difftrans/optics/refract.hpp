// Specular reflection and refraction directions, generic over the scalar
// type. All directions point away from the surface; n is a unit normal on
// either side; eta = IoR entered over IoR left (see fresnel.hpp).
#pragma once

#include "difftrans/ad/glm.hpp"
#include "difftrans/optics/fresnel.hpp"

namespace difftrans::optics {

// Mirror direction of wi about n, given cos_theta_i = dot(wi, n).
template <class S>
DT_HOST_DEVICE DT_FORCEINLINE Vec3<S> reflect(const Vec3<S>& wi, const Vec3<S>& n, const S& cos_theta_i) {
  return n * (S(2) * cos_theta_i) - wi;
}

// Mirror direction of wi about n (both unit, wi pointing away from the surface).
template <class S>
DT_HOST_DEVICE DT_FORCEINLINE Vec3<S> reflect(const Vec3<S>& wi, const Vec3<S>& n) {
  return reflect(wi, n, S(glm::dot(wi, n)));
}

template <class S>
struct RefractResult {
  Vec3<S> wt;  // transmitted direction (unit when wi and n are); zero when !valid
  S eta_it;    // relative IoR crossed (eta, or 1/eta from the back side)
  bool valid;  // false on total internal reflection
};

// Transmitted direction from the Fresnel quantities of the same interface
// (fresnel_dielectric(dot(wi, n), eta)), so that tracers pay for Snell once.
template <class S>
DT_HOST_DEVICE DT_FORCEINLINE Vec3<S> refract(const Vec3<S>& wi, const Vec3<S>& n, const S& cos_theta_i,
                                              const FresnelResult<S>& f) {
  return n * (cos_theta_i * f.eta_ti + f.cos_theta_t) - wi * f.eta_ti;
}

template <class S, class E>
DT_HOST_DEVICE RefractResult<S> refract(const Vec3<S>& wi, const Vec3<S>& n, const E& eta) {
  const S cos_i = glm::dot(wi, n);
  const detail::Snell<S> s = detail::snell(cos_i, S(eta));
  RefractResult<S> r;
  r.eta_it = s.eta_it;
  r.valid = !s.tir;
  if (s.tir) {
    r.wt = Vec3<S>(S(0), S(0), S(0));
  } else {
    const S cos_t = s.flipped ? s.cos_t : -s.cos_t;
    r.wt = n * (cos_i * s.eta_ti + cos_t) - wi * s.eta_ti;
  }
  return r;
}

}  // namespace difftrans::optics
