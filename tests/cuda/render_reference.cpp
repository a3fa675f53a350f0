// Host reference passes for tests/cuda/render.test.cu (see render_reference.hpp).
#include "render_reference.hpp"

#include <chrono>

#include "difftrans/render/passes.hpp"
#include "difftrans/render/ray_batch.hpp"

namespace dt_test {

namespace dr = difftrans::render;

namespace {
dr::PassOptions options(const dr::TraceSettings& trace, int samples_per_axis) {
  dr::PassOptions opt;
  opt.trace = trace;
  opt.samples_per_axis = samples_per_axis;
  return opt;
}
}  // namespace

std::vector<float> host_render_image(const dr::HostScene& s, const difftrans::scene::Camera& cam,
                                     const dr::TraceSettings& trace, int samples_per_axis) {
  return dr::render_image<float>(s, cam, options(trace, samples_per_axis));
}

void host_render_derivative(const dr::HostScene& s, const difftrans::scene::Camera& cam,
                            const float* const direction[dr::param_count], const dr::TraceSettings& trace,
                            int samples_per_axis, std::vector<float>& value, std::vector<float>& derivative) {
  dr::ImageDerivative d = dr::render_derivative(s, cam, direction, options(trace, samples_per_axis));
  value = std::move(d.value);
  derivative = std::move(d.derivative);
}

int host_render_gradient(const dr::HostScene& s, const difftrans::scene::Camera& cam, const float* pixel_adjoint,
                         dr::SceneGradient& grad, const dr::TraceSettings& trace, int samples_per_axis) {
  dr::PassStats st;
  dr::render_gradient<float>(s, cam, pixel_adjoint, grad, options(trace, samples_per_axis), &st);
  return st.max_tape_nodes;
}

HostRayGroups host_ray_group_gradient(const dr::HostScene& s, const std::vector<float>& rays, int group,
                                      const GroupLoss& loss, dr::SceneGradient& grad, const dr::TraceSettings& trace,
                                      float clip_geometry, float clip_ior) {
  std::vector<dr::BatchRay> batch(rays.size() / 6);
  for (std::size_t i = 0; i < batch.size(); ++i)
    batch[i] = {difftrans::Vec3f(rays[6 * i], rays[6 * i + 1], rays[6 * i + 2]),
                difftrans::Vec3f(rays[6 * i + 3], rays[6 * i + 4], rays[6 * i + 5])};
  const auto t0 = std::chrono::steady_clock::now();
  const dr::RayBatchResult r =
      dr::ray_group_gradient<float>(s, batch, group, loss, grad, options(trace, 1), true, clip_geometry, clip_ior);
  HostRayGroups out;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.loss = r.loss;
  for (const difftrans::Vec3f& c : r.radiance) out.radiance.insert(out.radiance.end(), {c.x, c.y, c.z});
  out.clipped_geometry = r.clipped_rays;
  out.clipped_ior = r.clipped_ior_rays;
  out.overflowed_rays = r.stats.overflowed_rays;
  return out;
}

}  // namespace dt_test
