// Device path: the generic optics probe instantiated in __global__ kernels for
// float, Dual<float, 1>, Dual<float, 4> and Var<float> (a tape per thread in
// local memory), compared with the same functor run on the host. Exits 77
// (skipped) when no CUDA device is present.
#include <cstdio>
#include <vector>

#include "difftrans/cuda/launch.cuh"
#include "difftrans/cuda/optics_probe.hpp"

namespace dc = difftrans::cuda;
namespace ad = difftrans::ad;

template <class S>
struct ProbeKernel {
  const dc::OpticsItem* items;
  dc::OpticsResult* out;
  __host__ __device__ void operator()(int i) const {
    if constexpr (ad::is_var_v<S>) {
      ad::Node<float> nodes[dc::optics_probe_tape_capacity];
      float adjoints[dc::optics_probe_tape_capacity];
      ad::Tape<float> tape(nodes, adjoints, dc::optics_probe_tape_capacity);
      out[i] = dc::optics_probe_gradient<S>(items[i], &tape);
      if (tape.overflowed()) out[i].value = -1.0f;
    } else {
      out[i] = dc::optics_probe_gradient<S>(items[i]);
    }
  }
};

template <class S>
int run(const char* name, const std::vector<dc::OpticsItem>& items) {
  const int n = int(items.size());
  std::vector<dc::OpticsResult> host(items.size()), device(items.size());
  ProbeKernel<S> on_host{items.data(), host.data()};
  for (int i = 0; i < n; ++i) on_host(i);
  dc::DeviceBuffer<dc::OpticsItem> d_items(items.size());
  dc::DeviceBuffer<dc::OpticsResult> d_out(items.size());
  d_items.upload(items.data());
  dc::launch(n, ProbeKernel<S>{d_items.data(), d_out.data()});
  dc::check(cudaDeviceSynchronize(), "synchronize");
  d_out.download(device.data());
  int bad = 0;
  for (int i = 0; i < n; ++i) {
    const auto close = [](float a, float b) { return std::abs(a - b) <= 1e-4f * std::max(1.0f, std::abs(b)); };
    bool ok = close(device[i].value, host[i].value);
    for (int k = 0; k < 4; ++k) ok = ok && close(device[i].grad[k], host[i].grad[k]);
    bad += !ok;
  }
  std::printf("%-16s %d items, %d differ from the host\n", name, n, bad);
  return bad;
}

int main() {
  if (dc::device_count() == 0) {
    std::printf("no CUDA device: device test skipped (the same kernels are tested on the host)\n");
    return 77;
  }
  const auto items = dc::make_optics_items(1 << 14, 3);
  int bad = 0;
  bad += run<float>("float", items);
  bad += run<ad::Dual<float, 1>>("Dual<float,1>", items);
  bad += run<ad::Dual<float, 4>>("Dual<float,4>", items);
  bad += run<ad::Var<float>>("Var<float>", items);
  return bad == 0 ? 0 : 1;
}
