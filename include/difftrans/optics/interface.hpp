// One event at a smooth dielectric interface: the reflected and refracted
// directions and their Fresnel weights R and T = 1 − R (T = 0 on total
// internal reflection). The building block of the recursive tracer.
#pragma once

#include "difftrans/optics/fresnel.hpp"
#include "difftrans/optics/refract.hpp"

namespace difftrans::optics {

template <class S>
struct InterfaceEvent {
  Vec3<S> wr;  // reflected direction
  Vec3<S> wt;  // refracted direction; zero on TIR
  S R, T;      // Fresnel weights, R + T = 1
  S cos_theta_t;  // cosine of wt against n (signed opposite to dot(wi, n)); 0 on TIR
  S eta_it;    // relative IoR crossed by the refracted ray
  bool tir;
};

// wi: unit direction towards where the light goes back to (away from the
// surface); n: unit normal on either side; eta: IoR behind n over IoR in front.
template <class S, class E>
DT_HOST_DEVICE InterfaceEvent<S> interface_event(const Vec3<S>& wi, const Vec3<S>& n, const E& eta) {
  const S cos_i = glm::dot(wi, n);
  const FresnelResult<S> f = fresnel_dielectric(cos_i, S(eta));
  InterfaceEvent<S> e;
  e.wr = reflect(wi, n, cos_i);
  e.R = f.R;
  e.T = S(1) - f.R;
  e.cos_theta_t = f.cos_theta_t;
  e.eta_it = f.eta_it;
  e.tir = f.tir;
  e.wt = f.tir ? Vec3<S>(S(0), S(0), S(0)) : refract(wi, n, cos_i, f);
  return e;
}

}  // namespace difftrans::optics
