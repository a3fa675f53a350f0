// The host half of bench/device/speed.cu, in a C++ translation unit of its own
// so that nvcc never instantiates the tracer with the host accelerator: the
// benchmark scenes and the host passes' timings.
#pragma once

#include <string>

#include "difftrans/render/host_scene.hpp"
#include "difftrans/scene/camera.hpp"

namespace dt_bench {

// data/meshes/<mesh>.obj in the unit box, IoR 1.472, homogeneous absorption,
// under venice_sunset (data/envmaps).
difftrans::render::HostScene speed_scene(const std::string& mesh);

struct HostTimes {
  double primal_seconds = 0, gradient_seconds = 0;
  long long primal_segments = 0, gradient_segments = 0;
  int threads = 0;
};

// The best of `repeats` runs of render_image and render_gradient (an adjoint of ones).
HostTimes time_host_passes(const difftrans::render::HostScene& s, const difftrans::scene::Camera& cam,
                           const difftrans::render::TraceSettings& trace, int samples_per_axis, int repeats);

}  // namespace dt_bench
