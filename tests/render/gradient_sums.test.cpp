// render::DoubleSums: which buffers a reverse pass sums in double, where the
// adds go while it lives, and what a float sum of many small adds loses.
#include <cstdint>
#include <vector>

#include <doctest/doctest.h>

#include "support/scenes.hpp"

#include "difftrans/ad/params.hpp"
#include "difftrans/render/gradient_sums.hpp"

TEST_CASE("DoubleSums gives the IoR and the absorption double sums, added into the float gradient") {
  using namespace difftrans;
  const render::HostScene s = dt_test::sphere_scene();
  render::SceneGradient grad(s);
  ad::ParamSet set = s.params();
  grad.attach(set);
  grad.ior[0] = 2.0f;  // what a pass before this one left: kept, the sums added to it
  {
    const render::DoubleSums sums(set);
    for (int b = 0; b < render::param_count; ++b) {
      CAPTURE(b);
      CHECK((set.buffers[b].wide_gradient != nullptr) == render::sums_in_double(b));
    }
    // 2^24 adds of 1e-3: a float running sum rounds every add to its ulp
    // (past 2^15 an add is below half an ulp and lost) and ends 2 % low; the
    // double sum does not
    const double exact = double(1 << 24) * double(1e-3f);
    float in_float = 0.0f;
    for (std::int32_t k = 0; k < (1 << 24); ++k) {
      ad::detail::add_gradient(set.buffers[render::param_ior], 0, 1e-3f);
      in_float += 1e-3f;
    }
    ad::detail::add_gradient(set.buffers[render::param_absorption], 1, 0.5f);
    ad::detail::add_gradient(set.buffers[render::param_positions], 4, 0.25f);  // float, directly
    CHECK(grad.ior[0] == 2.0f);                        // nothing in the float array yet
    CHECK(in_float < 0.99 * exact);                    // the float sum lost 2 % of it
    CHECK(grad.positions[4] == 0.25f);
    sums.add_to();
  }
  CHECK(grad.ior[0] == doctest::Approx(2.0 + double(1 << 24) * double(1e-3f)).epsilon(1e-6));
  CHECK(grad.absorption[1] == 0.5f);
  CHECK(grad.absorption[0] == 0.0f);
}

TEST_CASE("DoubleSums leaves alone a buffer the pass does not differentiate") {
  using namespace difftrans;
  const render::HostScene s = dt_test::sphere_scene();
  ad::ParamSet set = s.params();  // no gradient arrays attached: nothing to sum into
  const render::DoubleSums sums(set);
  for (int b = 0; b < render::param_count; ++b) CHECK(set.buffers[b].wide_gradient == nullptr);
  sums.add_to();  // and nothing to add
}
