// Host half of bench/device/speed.cu (see speed_host.hpp).
#include "speed_host.hpp"

#include <cstddef>
#include <vector>

#include "difftrans/core/parallel.hpp"
#include "difftrans/render/passes.hpp"
#include "support/scenes.hpp"
#include "support/timing.hpp"

namespace dt_bench {

namespace dr = difftrans::render;

dr::HostScene speed_scene(const std::string& mesh) {
  dr::HostScene s = venice_scene(mesh, 1.472f);
  s.set_homogeneous_absorption(difftrans::Vec3f(0.3f, 0.6f, 1.2f));
  return s;
}

HostTimes time_host_passes(const dr::HostScene& s, const difftrans::scene::Camera& cam,
                           const dr::TraceSettings& trace, int samples_per_axis, int repeats) {
  dr::PassOptions opt;
  opt.trace = trace;
  opt.samples_per_axis = samples_per_axis;
  HostTimes t;
  t.threads = difftrans::ThreadPool::global().size();
  dr::PassStats ps, gs;
  t.primal_seconds = best_seconds([&] { dr::render_image<float>(s, cam, opt, &ps); }, repeats);
  const std::vector<float> adjoint(std::size_t(cam.width) * std::size_t(cam.height) * 3, 1.0f);
  dr::SceneGradient grad(s);
  t.gradient_seconds =
      best_seconds([&] { dr::render_gradient<float>(s, cam, adjoint.data(), grad, opt, &gs); }, repeats);
  t.primal_segments = ps.trace.segments;
  t.gradient_segments = gs.trace.segments;
  return t;
}

}  // namespace dt_bench
