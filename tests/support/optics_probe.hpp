// Test fixture: a per-item optics kernel — Fresnel split, refraction and
// Beer–Lambert attenuation along the refracted segment — written once and run
// as float, Dual or Var, on the host and inside CUDA kernels. It checks that
// the generic path compiles and agrees on both sides (tests/cuda), and it is
// the workload of the optics micro-benchmark (bench/optics.bench.cpp).
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "difftrans/ad/ad.hpp"
#include "difftrans/optics/optics.hpp"

namespace dt_test {

namespace ad = difftrans::ad;
namespace optics = difftrans::optics;
using difftrans::Vec3;

// One input: a direction and normal at an interface, the IoR, an RGB
// absorption coefficient and the length of the segment inside.
struct OpticsItem {
  float wi[3];
  float n[3];
  float eta;
  float sigma[3];
  float length;
};

// The probe's value and its gradient with respect to (eta, sigma.r, sigma.g, sigma.b).
struct OpticsResult {
  float value;
  float grad[4];
  int overflowed;  // Var: the tape ran out of nodes (set by the caller that owns the tape)
};

// The radiance-like scalar the probe computes, for any scalar S.
template <class S>
DT_HOST_DEVICE S optics_probe(const OpticsItem& it, const S& eta, const Vec3<S>& sigma) {
  const Vec3<S> wi(S(it.wi[0]), S(it.wi[1]), S(it.wi[2]));
  const Vec3<S> n(S(it.n[0]), S(it.n[1]), S(it.n[2]));
  const optics::InterfaceEvent<S> e = optics::interface_event(wi, n, eta);
  const Vec3<S> att = optics::transmittance(sigma, S(it.length));
  const S reflected = e.R * (S(0.2f) + e.wr.y * e.wr.y);
  const S transmitted = e.T * (att.x + S(0.5f) * att.y + S(0.25f) * att.z) * (S(1.5f) + e.wt.z);
  return reflected + transmitted;
}

// Value and gradient with scalar S: Dual<float, N> (N = 1: d/deta only; N >= 4:
// all four), Var<float> (recorded on the caller's tape), or float (value only).
template <class S>
DT_HOST_DEVICE OpticsResult optics_probe_gradient(const OpticsItem& it, ad::Tape<float>* tape = nullptr) {
  OpticsResult r{};
  if constexpr (ad::is_dual_v<S>) {
    constexpr int N = ad::dual_lanes_v<S>;
    const S eta = S::variable(it.eta, 0);
    Vec3<S> sigma;
    for (int c = 0; c < 3; ++c) sigma[c] = N > c + 1 ? S::variable(it.sigma[c], c + 1) : S(it.sigma[c]);
    const S y = optics_probe(it, eta, sigma);
    r.value = y.value;
    for (int k = 0; k < 4 && k < N; ++k) r.grad[k] = y.grad[k];
  } else if constexpr (ad::is_var_v<S>) {
    tape->reset();
    const S eta = tape->variable(it.eta);
    const Vec3<S> sigma(tape->variable(it.sigma[0]), tape->variable(it.sigma[1]), tape->variable(it.sigma[2]));
    const S y = optics_probe(it, eta, sigma);
    tape->backward(y);
    r.value = y.value;
    r.grad[0] = tape->adjoint(eta);
    for (int c = 0; c < 3; ++c) r.grad[c + 1] = tape->adjoint(sigma[c]);
  } else {
    r.value = optics_probe(it, S(it.eta), Vec3<S>(S(it.sigma[0]), S(it.sigma[1]), S(it.sigma[2])));
  }
  return r;
}

// A deterministic, varied input set: directions from both sides of the
// surface (some past the critical angle), IoR in [1, 2.5] and absorption in
// [0, 8) per unit length. Host only.
inline std::vector<OpticsItem> make_optics_items(int count, std::uint32_t seed = 1) {
  std::uint32_t state = seed * 747796405u + 2891336453u;
  const auto uniform = [&state]() {  // PCG-style hash to [0, 1)
    state = state * 747796405u + 2891336453u;
    std::uint32_t w = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return float((w >> 22u) ^ w) * 0x1p-32f;
  };
  std::vector<OpticsItem> items(std::size_t(count < 0 ? 0 : count));
  for (OpticsItem& it : items) {
    const float z = 2.0f * uniform() - 1.0f, phi = 6.2831853f * uniform(), s = std::sqrt(1.0f - z * z);
    it.wi[0] = s * std::cos(phi);
    it.wi[1] = s * std::sin(phi);
    it.wi[2] = z;
    it.n[0] = 0.0f;
    it.n[1] = 0.0f;
    it.n[2] = 1.0f;
    it.eta = 1.0f + 1.5f * uniform();
    for (float& c : it.sigma) c = 8.0f * uniform();
    it.length = 0.05f + uniform();
  }
  return items;
}

// Tape nodes one probe records (with its four leaves); a per-thread budget.
inline constexpr int optics_probe_tape_capacity = 160;

}  // namespace dt_test
