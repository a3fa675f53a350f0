// Host reference passes (render/passes.hpp, on HostScene's accelerator) for
// the device render test, compiled in a C++ translation unit of their own so
// that nvcc never instantiates the tracer with the host accelerator.
#pragma once

#include <vector>

#include "difftrans/render/host_scene.hpp"
#include "difftrans/scene/camera.hpp"

namespace dt_test {

std::vector<float> host_render_image(const difftrans::render::HostScene& s, const difftrans::scene::Camera& cam,
                                     const difftrans::render::TraceSettings& trace, int samples_per_axis);

void host_render_derivative(const difftrans::render::HostScene& s, const difftrans::scene::Camera& cam,
                            const float* const direction[difftrans::render::param_count],
                            const difftrans::render::TraceSettings& trace, int samples_per_axis,
                            std::vector<float>& value, std::vector<float>& derivative);

// Returns the largest tape (nodes) of any ray.
int host_render_gradient(const difftrans::render::HostScene& s, const difftrans::scene::Camera& cam,
                         const float* pixel_adjoint, difftrans::render::SceneGradient& grad,
                         const difftrans::render::TraceSettings& trace, int samples_per_axis);

}  // namespace dt_test
