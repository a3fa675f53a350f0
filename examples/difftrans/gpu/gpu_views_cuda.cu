// GpuViewTracer and GpuBatchTracer on the device passes of cuda/render.cuh (a build with the CUDA backend).
#include <cuda_runtime.h>

#include <cstdint>
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

void GpuViewTracer::update(const render::HostScene& s) { impl_->scene.update(s, impl_->bvh); }

struct GpuBatchTracer::Impl {
  std::vector<float> positions;       // of the BVH below
  std::vector<std::int32_t> triangles;
  std::unique_ptr<accel::Bvh> bvh;
  std::unique_ptr<cuda::DeviceScene> scene;
};

GpuBatchTracer::GpuBatchTracer() {
  const std::string why = gpu_unavailable_reason();
  if (!why.empty()) throw std::runtime_error(why);
  impl_ = std::make_unique<Impl>();
}

GpuBatchTracer::~GpuBatchTracer() = default;

GpuBatchStats GpuBatchTracer::gradient(const render::HostScene& s, const std::vector<float>& rays, int group,
                                       const GroupLoss& loss, render::SceneGradient& grad,
                                       const render::TraceSettings& trace, float clip_geometry, float clip_ior) {
  Impl& m = *impl_;
  if (!m.bvh || m.positions != s.mesh.positions || m.triangles != s.mesh.triangles) {
    m.bvh = std::make_unique<accel::Bvh>(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(),
                                         s.mesh.num_triangles(), "gpu training pass");
    m.positions = s.mesh.positions;
    m.triangles = s.mesh.triangles;
  }
  if (m.scene) m.scene->update(s, *m.bvh);
  else m.scene = std::make_unique<cuda::DeviceScene>(s, *m.bvh);
  cuda::PassOptions opt;
  opt.trace = trace;
  const cuda::RayGroupStats st =
      cuda::ray_group_gradient(*m.scene, rays, group, loss, grad, opt, clip_geometry, clip_ior);
  GpuBatchStats out;
  out.loss = st.loss;
  out.rays = (long long)st.rays;
  out.segments = (long long)st.segments;
  out.dropped_rays = (long long)st.waves.dropped_pixels * group;
  out.redone_groups = (long long)st.waves.redone_pixels;
  out.clipped_geometry = (long long)st.clipped_geometry;
  out.clipped_ior = (long long)st.clipped_ior;
  out.max_tape_nodes = int(st.max_tape_nodes);
  out.milliseconds = st.milliseconds;
  return out;
}

}  // namespace difftrans::cli
