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
  // Reverse mode: each segment traced again when its subtrees are done
  // (render::trace_recomputed), on a tape of one segment, instead of the
  // path from the camera kept on it (render::trace_streamed); the same
  // gradient, each segment traced twice.
  bool recompute = false;
};

// The image (value) and its derivative along one direction in parameter
// space, width·height·3 each.
struct ImageDerivative {
  std::vector<float> value, derivative;
};

// Sample k of the n × n stratified samples (stratum centres) of pixel `pix`
// (row-major: pix = y · width + x), j-major: k = j · n + i. Every pass, host
// or device, samples a pixel this way; each sample weighs 1 / n².
// pixel_sample_point: where that sample lies, in continuous pixel coordinates.
DT_HOST_DEVICE inline Vec2f pixel_sample_point(const scene::Camera& cam, int n, std::int64_t pix, int k) {
  const float inv = 1.0f / float(n);
  const int x = int(pix % cam.width), y = int(pix / cam.width);
  return Vec2f(float(x) + (float(k % n) + 0.5f) * inv, float(y) + (float(k / n) + 0.5f) * inv);
}
DT_HOST_DEVICE inline scene::Ray pixel_sample(const scene::Camera& cam, int n, std::int64_t pix, int k) {
  const Vec2f p = pixel_sample_point(cam, n, pix, k);
  return cam.ray_through(p.x, p.y);
}

// Calls f(origin, direction, weight) for the n² samples of pixel `pix`, in
// the order of pixel_sample.
template <class F>
DT_HOST_DEVICE void for_each_pixel_sample(const scene::Camera& cam, int n, std::int64_t pix, F&& f) {
  const float weight = 1.0f / float(n * n);
  for (int k = 0; k < n * n; ++k) {
    const scene::Ray r = pixel_sample(cam, n, pix, k);
    f(r.origin, r.direction, weight);
  }
}

}  // namespace difftrans::render
