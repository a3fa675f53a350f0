// Host reference passes (render/passes.hpp, on HostScene's accelerator) for
// the device render test, compiled in a C++ translation unit of their own so
// that nvcc never instantiates the tracer with the host accelerator.
#pragma once

#include <cstdint>
#include <functional>
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

// render::ray_group_gradient over rays of 6 floats (origin, direction),
// `group` a group, the vertex and IoR clips on; returns the loss, the
// radiance (3 per ray) and the clipped group counts.
struct HostRayGroups {
  double loss = 0.0, seconds = 0.0;
  std::vector<float> radiance;
  long long clipped_geometry = 0, clipped_ior = 0, overflowed_rays = 0;
};
using GroupLoss = std::function<double(std::int64_t, const difftrans::Vec3f*, difftrans::Vec3f*)>;
HostRayGroups host_ray_group_gradient(const difftrans::render::HostScene& s, const std::vector<float>& rays, int group,
                                      const GroupLoss& loss, difftrans::render::SceneGradient& grad,
                                      const difftrans::render::TraceSettings& trace, float clip_geometry,
                                      float clip_ior);

}  // namespace dt_test
