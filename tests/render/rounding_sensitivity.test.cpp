// The passes' sensitivity to rounding (render/rounding_sensitivity.hpp): the
// same view from an eye moved by one float step. At depth 4 every gradient
// stays put to 1e-2 or better, so a change that makes shallow gradients
// chaotic fails here. At depth 16 the absorption and environment gradients
// still do, while the IoR's and the vertices' move by their own size (what
// tests/cuda/render.test.cu leaves out of its device check).
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "support/ad_check.hpp"
#include "support/scenes.hpp"
#include "support/shapes.hpp"

#include "difftrans/render/rounding_sensitivity.hpp"

using namespace dt_test;
using difftrans::Vec3f;

namespace {

std::vector<float> wavy_adjoint(int size) {
  std::vector<float> a(std::size_t(size) * std::size_t(size) * 3);
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = 0.5f + 0.5f * std::sin(0.37f * float(i));
  return a;
}

}  // namespace

TEST_CASE("one ulp of the eye: shallow gradients stay, deep ones of the IoR and the vertices do not") {
  using namespace difftrans;
  const render::HostScene s = spot_scene();
  for (const int depth : {4, 16}) {
    CAPTURE(depth);
    const int size = depth == 4 ? 64 : 128;
    const scene::Camera cam =
        scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, size, size);
    render::PassOptions opt;
    opt.trace.max_depth = depth;
    opt.samples_per_axis = depth == 4 ? 2 : 1;
    const std::vector<float> adjoint = wavy_adjoint(size);
    const render::RoundingSensitivity r = render::rounding_sensitivity(s, cam, opt, adjoint.data());
    std::printf("depth %2d: pixels moved %.4f%% (d/dIoR %.4f%%); gradients moved: IoR %.3g, positions %.3g,"
                " absorption %.3g, environment %.3g\n",
                depth, 100 * r.image_share, 100 * r.derivative_share, r.ior, r.positions, r.absorption,
                r.environment);
    CHECK(r.absorption < 1e-3);
    CHECK(r.environment < 1e-3);
    if (depth == 4) {
      CHECK(r.image_share < 1e-3);
      CHECK(r.ior < 1e-2);
      CHECK(r.positions < 1e-2);
    } else {
      CHECK(r.image_share > 1e-3);  // deep paths through the ears and legs diverge
    }
  }
  // the moved eye is one float step away, and only that
  const scene::Camera cam = scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, 8, 8);
  const scene::Camera moved = render::moved_eye(cam, 0);
  CHECK(moved.camera_to_world[3][0] == std::nextafter(cam.camera_to_world[3][0], 1e30f));
  CHECK(moved.camera_to_world[3][1] == cam.camera_to_world[3][1]);
}
