// What every pass of the tracer over a camera image shares, on the host
// (render/passes.hpp) and on the device (cuda/render.cuh): its options, the
// pattern of sub-pixel samples, and the image-with-derivative it returns.
// Free of any accelerator, so device translation units include it too.
#pragma once

#include <cstdint>
#include <vector>

#include "difftrans/render/tracer.hpp"
#include "difftrans/scene/camera.hpp"

namespace difftrans::render {

// The host passes' options (the device's: cuda::PassOptions, with its own tape schedule).
struct PassOptions {
  TraceSettings trace;
  int samples_per_axis = 1;                  // n: n² sub-pixel samples at the centres of an n×n grid
  std::int32_t tape_capacity = 1 << 20;      // nodes per ray (reverse mode)
  std::int32_t leaf_log_capacity = 1 << 16;  // parameter leaves per ray (reverse mode)
};

// The image (value) and its derivative along one direction in parameter
// space, width·height·3 each.
struct ImageDerivative {
  std::vector<float> value, derivative;
};

// Calls f(origin, direction, weight) for the n × n stratified samples
// (stratum centres) of pixel `pix` (row-major: pix = y · width + x), j-major;
// weight = 1 / n². Every pass, host or device, samples a pixel this way, in
// this order.
template <class F>
DT_HOST_DEVICE void for_each_pixel_sample(const scene::Camera& cam, int n, std::int64_t pix, F&& f) {
  const float inv = 1.0f / float(n), weight = 1.0f / float(n * n);
  const int x = int(pix % cam.width), y = int(pix / cam.width);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const scene::Ray r = cam.generate_ray(x, y, (float(i) + 0.5f) * inv, (float(j) + 0.5f) * inv);
      f(r.origin, r.direction, weight);
    }
}

}  // namespace difftrans::render
