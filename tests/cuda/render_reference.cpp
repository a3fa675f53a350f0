// Host reference passes for tests/cuda/render.test.cu (see render_reference.hpp).
#include "render_reference.hpp"

#include "difftrans/render/passes.hpp"

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

}  // namespace dt_test
