// The recomputed reverse mode (render/recomputed_trace.hpp) against the
// whole tape: the same gradient of a sum of rays on a sphere under eight
// settings of the tracer and on spot at depth 16, each segment making the
// same children when it is traced again, and a tape of half a segment.
#include "support/trace_gradients.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

using namespace dt_test;

TEST_CASE("recomputed reverse mode: the same gradient on a tape of half a segment") {
  HostScene s = make_scene(make_icosphere(0.5f, 2), 1.5f);
  smooth_environment(s);
  const auto rays = rays_towards_centre(Vec3f(0.2f, 0.4f, 3.0f), 0.45f, 12);
  const Vec3d w(0.7, 1.0, 1.3);
  TraceSettings one;  // the camera ray's segment and its two children
  one.max_depth = 1;
  set_case_absorption(s, 0);
  const std::int32_t clear_one_peak = whole_tape(s, rays, one).peak;
  for (const GradientCase& c : gradient_cases()) {
    CAPTURE(c.name);
    set_case_absorption(s, c.absorption);
    const SceneGradient full = loss_gradient(s, rays, w, c.ts);
    std::vector<Vec3d> radiance;
    std::int32_t peak = 0;
    int mismatched = 0;
    const SceneGradient again = streamed_gradient(s, rays, w, c.ts, &radiance, &peak, true, &mismatched);
    CHECK(mismatched == 0);
    for (std::size_t i = 0; i < rays.size(); ++i)
      for (int k = 0; k < 3; ++k) CHECK(radiance[i][k] == doctest::Approx(trace_value<double>(s, rays[i], c.ts)[k]).epsilon(1e-12));
    CHECK(same_gradient(full.positions, again.positions, "positions") > 0.0f);
    CHECK(same_gradient(full.ior, again.ior, "ior") > 0.0f);
    CHECK(same_gradient(full.environment, again.environment, "environment") > 0.0f);
    const float absorption_scale = same_gradient(full.absorption, again.absorption, "absorption");
    CHECK((c.absorption == 0) == (absorption_scale == 0.0f));
    // Below the streamed tape's; no more than the whole tape of the camera
    // ray's segment and its children, but for a grid integrated exactly (a
    // segment records a node group per cell crossed, and deeper chords can
    // be longer). A grid integrated by samples is swept one sample at a
    // time: no more than that whole tape through clear glass.
    std::vector<Vec3d> unused;
    std::int32_t streamed_peak = 0;
    streamed_gradient(s, rays, w, c.ts, &unused, &streamed_peak);
    const std::int32_t one_peak = whole_tape(s, rays, one).peak;
    MESSAGE(std::string(c.name), ": largest tape recomputed ", peak, " nodes, streamed ", streamed_peak,
            ", the first interaction's whole tape ", one_peak);
    CHECK(peak < streamed_peak);
    if (c.absorption != 2) CHECK(peak <= one_peak);
    if (c.ts.integration.samples > 0) CHECK(peak <= clear_one_peak);
  }
  SUBCASE("spot at depth 16: a segment's tape, not a path's") {
    const SpotDeepTree spot(w);
    std::vector<Vec3d> radiance;
    std::int32_t streamed_peak = 0, peak = 0;
    int mismatched = 0;
    streamed_gradient(spot.scene, spot.rays, w, spot.settings, &radiance, &streamed_peak);
    const SceneGradient again =
        streamed_gradient(spot.scene, spot.rays, w, spot.settings, &radiance, &peak, true, &mismatched);
    CHECK(mismatched == 0);
    CHECK(same_gradient(spot.full.positions, again.positions, "positions") > 0.0f);
    CHECK(same_gradient(spot.full.ior, again.ior, "ior") > 0.0f);
    MESSAGE("spot at depth 16: largest tape streamed ", streamed_peak, " nodes, recomputed ", peak);
    CHECK(4 * peak < streamed_peak);
  }
}
