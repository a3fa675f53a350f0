// The command's way to the GPU (--device cpu|cuda|auto): a tracer of whole
// views through the device passes (docs/cuda.md), compiled by nvcc into
// gpu/gpu_views_cuda.cu when the build has the CUDA backend, and as
// gpu/gpu_views_none.cpp (which says why there is no GPU) when it has not.
// This header stays free of io/ and of the host accelerator, so that nvcc
// compiles what includes it.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/pass_options.hpp"
#include "difftrans/scene/camera.hpp"

namespace difftrans::cli {

// Empty when this build and machine can trace on a GPU; else why not.
std::string gpu_unavailable_reason();

// The work of one GPU view, as render::PassStats counts it on the host.
struct GpuViewStats {
  long long rays = 0, segments = 0;
  double milliseconds = 0;  // kernel time
};

// Traces views of one scene on the GPU: the scene and a BVH of its mesh are
// uploaded once, when it is made. Its distant environment only: a near
// field stays on the host (the constructor throws std::invalid_argument).
class GpuViewTracer {
 public:
  explicit GpuViewTracer(const render::HostScene& s);
  ~GpuViewTracer();
  GpuViewTracer(const GpuViewTracer&) = delete;
  GpuViewTracer& operator=(const GpuViewTracer&) = delete;
  // Linear RGB, width·height·3, as render::render_image.
  std::vector<float> render(const scene::Camera& cam, const render::PassOptions& options, GpuViewStats* stats);
  // After the scene's materials or distant environment changed (not its
  // mesh): uploads them again, keeping the BVH.
  void update(const render::HostScene& s);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// What one training pass on the GPU did (cuda::RayGroupStats, in plain numbers).
struct GpuBatchStats {
  double loss = 0.0;
  long long rays = 0, segments = 0;
  long long dropped_rays = 0;     // rays of groups whose gradient is missing (even the longest tape overflowed)
  long long redone_groups = 0;    // groups redone on a longer tape
  long long clipped_geometry = 0, clipped_ior = 0;  // groups whose vertex / IoR gradient was clipped
  int max_tape_nodes = 0;
  double milliseconds = 0;        // kernel time
};

// Stage 2's training pass (render::ray_group_gradient) on the GPU: the
// scene is uploaded at every pass (its materials, environment and vertices
// change between steps), its BVH rebuilt when the vertices moved.
class GpuBatchTracer {
 public:
  // loss(j, L, dL): group j's radiances L, writes dLoss/dL, returns its loss.
  using GroupLoss = std::function<double(std::int64_t, const Vec3f*, Vec3f*)>;
  GpuBatchTracer();
  ~GpuBatchTracer();
  GpuBatchTracer(const GpuBatchTracer&) = delete;
  GpuBatchTracer& operator=(const GpuBatchTracer&) = delete;
  // rays: origin and direction, 6 floats each, `group` consecutive rays a
  // group. Adds the gradient to `grad` (the buffers s.differentiate marks).
  GpuBatchStats gradient(const render::HostScene& s, const std::vector<float>& rays, int group, const GroupLoss& loss,
                         render::SceneGradient& grad, const render::TraceSettings& trace, float clip_geometry,
                         float clip_ior);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace difftrans::cli
