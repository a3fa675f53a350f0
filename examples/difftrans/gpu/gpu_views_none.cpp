// GpuViewTracer and GpuBatchTracer in a build without the CUDA backend: there is no GPU to use.
#include <stdexcept>
#include <string>
#include <vector>

#include "gpu_views.hpp"

namespace difftrans::cli {

std::string gpu_unavailable_reason() {
  return "this difftrans was built without the CUDA backend (no nvcc when it was configured; docs/cuda.md)";
}

struct GpuViewTracer::Impl {};

GpuViewTracer::GpuViewTracer(const render::HostScene&) { throw std::runtime_error(gpu_unavailable_reason()); }

GpuViewTracer::~GpuViewTracer() = default;

std::vector<float> GpuViewTracer::render(const scene::Camera&, const render::PassOptions&, GpuViewStats*) {
  throw std::runtime_error(gpu_unavailable_reason());
}

void GpuViewTracer::update(const render::HostScene&) { throw std::runtime_error(gpu_unavailable_reason()); }

struct GpuBatchTracer::Impl {};

GpuBatchTracer::GpuBatchTracer() { throw std::runtime_error(gpu_unavailable_reason()); }

GpuBatchTracer::~GpuBatchTracer() = default;

GpuBatchStats GpuBatchTracer::gradient(const render::HostScene&, const std::vector<float>&, int, const GroupLoss&,
                                       render::SceneGradient&, const render::TraceSettings&, float, float) {
  throw std::runtime_error(gpu_unavailable_reason());
}

}  // namespace difftrans::cli
