// Device path: the generic optics probe instantiated in __global__ kernels for
// float, Dual<float, 1>, Dual<float, 4> and Var<float> (a tape per thread in
// local memory), compared with the same functor run on the host and with the
// probe in double precision. Exits 77 (skipped) when no CUDA device is present.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "difftrans/cuda/launch.cuh"
#include "support/optics_probe.hpp"

namespace dc = difftrans::cuda;
namespace dp = dt_test;  // the probe
namespace ad = difftrans::ad;

template <class S>
struct ProbeKernel {
  const dp::OpticsItem* items;
  dp::OpticsResult* out;
  __host__ __device__ void operator()(int i) const {
    if constexpr (ad::is_var_v<S>) {
      ad::Node<float> nodes[dp::optics_probe_tape_capacity];
      float adjoints[dp::optics_probe_tape_capacity];
      ad::Tape<float> tape(nodes, adjoints, dp::optics_probe_tape_capacity);
      out[i] = dp::optics_probe_gradient<S>(items[i], &tape);
      out[i].overflowed = tape.overflowed() ? 1 : 0;
    } else {
      out[i] = dp::optics_probe_gradient<S>(items[i]);
    }
  }
};

// Lanes of the gradient that S computes (0: the value only).
template <class S>
constexpr int gradient_lanes() {
  if constexpr (ad::is_dual_v<S>) return ad::dual_lanes_v<S> < 4 ? ad::dual_lanes_v<S> : 4;
  else if constexpr (ad::is_var_v<S>) return 4;
  else return 0;
}

// Device against host, both against the same probe in double precision
// (Dual<double, 4>): float results of an ill-conditioned item (a derivative
// with cancellation near the critical angle) may differ by more than a fixed
// tolerance between two correct float implementations, so the device may be
// off the double result by 1.5e-4 (relative to max(1, |value|)) plus four
// times what the host is off.
template <class S>
int run(const char* name, const std::vector<dp::OpticsItem>& items) {
  const int n = int(items.size());
  std::vector<dp::OpticsResult> host(items.size()), device(items.size()), reference(items.size());
  ProbeKernel<S> on_host{items.data(), host.data()};
  for (int i = 0; i < n; ++i) on_host(i);
  for (int i = 0; i < n; ++i) reference[std::size_t(i)] = dp::optics_probe_gradient<ad::Dual<double, 4>>(items[std::size_t(i)]);
  dc::DeviceBuffer<dp::OpticsItem> d_items(items.size());
  dc::DeviceBuffer<dp::OpticsResult> d_out(items.size());
  d_items.upload(items.data());
  dc::launch(n, ProbeKernel<S>{d_items.data(), d_out.data()});
  dc::check(cudaDeviceSynchronize(), "synchronize");
  d_out.download(device.data());
  int bad = 0, overflowed = 0, off_host = 0;
  double worst = 0;  // largest |device − reference| over its allowance
  for (int i = 0; i < n; ++i) {
    const auto within = [&](float d, float h, float r) {
      const double allowed = 1.5e-4 * std::max(1.0, std::abs(double(r))) + 4.0 * std::abs(double(h) - r);
      worst = std::max(worst, std::abs(double(d) - r) / allowed);
      return std::abs(double(d) - r) <= allowed;
    };
    // a gradient cut short by a full tape is a failure even when both sides agree on it
    const bool full = device[i].overflowed || host[i].overflowed;
    bool ok = !full && within(device[i].value, host[i].value, reference[i].value);
    bool same = std::abs(device[i].value - host[i].value) <= 1e-4f * std::max(1.0f, std::abs(host[i].value));
    for (int k = 0; k < gradient_lanes<S>(); ++k) {
      ok = within(device[i].grad[k], host[i].grad[k], reference[i].grad[k]) && ok;
      same = same && std::abs(device[i].grad[k] - host[i].grad[k]) <= 1e-4f * std::max(1.0f, std::abs(host[i].grad[k]));
    }
    bad += !ok;
    overflowed += full;
    off_host += !same;
    if (!ok && bad <= 3) {
      const dp::OpticsItem& it = items[std::size_t(i)];
      const float cos_i = it.wi[0] * it.n[0] + it.wi[1] * it.n[1] + it.wi[2] * it.n[2];
      std::printf("  item %d (cos_i %.9g, eta %.9g): value %.9g / %.9g / %.9g, gradient", i, cos_i, it.eta,
                  device[i].value, host[i].value, reference[i].value);
      for (int k = 0; k < 4; ++k) std::printf(" %.6g / %.6g / %.6g", device[i].grad[k], host[i].grad[k], reference[i].grad[k]);
      std::printf(" (device / host / double)\n");
    }
  }
  std::printf("%-16s %d items: %d off the double reference beyond their allowance (largest share of it %.3g),"
              " %d differ from the host by > 1e-4, %d overflowed the tape\n",
              name, n, bad, worst, off_host, overflowed);
  return bad;
}

int main() {
  if (dc::device_count() == 0) {
    std::printf("no CUDA device: device test skipped (the same kernels are tested on the host)\n");
    return 77;
  }
  const auto items = dp::make_optics_items(1 << 14, 3);
  int bad = 0;
  bad += run<float>("float", items);
  bad += run<ad::Dual<float, 1>>("Dual<float,1>", items);
  bad += run<ad::Dual<float, 4>>("Dual<float,4>", items);
  bad += run<ad::Var<float>>("Var<float>", items);
  return bad == 0 ? 0 : 1;
}
