// GpuViewTracer on the device passes of cuda/render.cuh (a build with the CUDA backend).
#include <cuda_runtime.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/accel/bvh.hpp"
#include "difftrans/cuda/render.cuh"
#include "gpu_views.hpp"

namespace difftrans::cli {

std::string gpu_unavailable_reason() {
  int n = 0;
  const cudaError_t e = cudaGetDeviceCount(&n);
  if (e != cudaSuccess) {
    const std::string why = cudaGetErrorString(e);
    (void)cudaGetLastError();
    return "no CUDA device is usable (" + why + ")";
  }
  return n > 0 ? std::string() : std::string("no CUDA device is present");
}

struct GpuViewTracer::Impl {
  accel::Bvh bvh;
  cuda::DeviceScene scene;
  explicit Impl(const render::HostScene& s)
      : bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(), s.mesh.num_triangles(),
            "gpu view tracer"),
        scene(s, bvh) {}
};

GpuViewTracer::GpuViewTracer(const render::HostScene& s) {
  const std::string why = gpu_unavailable_reason();
  if (!why.empty()) throw std::runtime_error(why);
  impl_ = std::make_unique<Impl>(s);
}

GpuViewTracer::~GpuViewTracer() = default;

std::vector<float> GpuViewTracer::render(const scene::Camera& cam, const render::PassOptions& options,
                                         GpuViewStats* stats) {
  cuda::PassOptions opt;
  opt.trace = options.trace;
  opt.samples_per_axis = options.samples_per_axis;
  cuda::DevicePassStats st;
  std::vector<float> image = cuda::render_image(impl_->scene, cam, opt, &st);
  if (stats) *stats = GpuViewStats{(long long)st.rays, (long long)st.segments, st.milliseconds};
  return image;
}

}  // namespace difftrans::cli
