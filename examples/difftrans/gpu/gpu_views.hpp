// The command's way to the GPU (--device cpu|cuda|auto): a tracer of whole
// views through the device passes (docs/cuda.md), compiled by nvcc into
// gpu/gpu_views_cuda.cu when the build has the CUDA backend, and as
// gpu/gpu_views_none.cpp (which says why there is no GPU) when it has not.
// This header stays free of io/ and of the host accelerator, so that nvcc
// compiles what includes it.
#pragma once

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

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace difftrans::cli
