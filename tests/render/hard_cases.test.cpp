// The hard cases of render/hard_cases.hpp (edge and vertex hits, grazing,
// total internal reflection, a camera inside, exp underflow, the map's seam
// and poles, IoR 1, a direction not finite, a zero-area triangle): values and
// gradients stay finite on every one — difftrans report prints these same
// counts — and the check does count what is not finite.
#include "support/ad_check.hpp"

#include <cstdint>
#include <limits>

#include "difftrans/render/hard_cases.hpp"

using difftrans::Vec3f;
using difftrans::render::TraceSettings;

TEST_CASE("hard cases stay finite, values and gradients") {
  TraceSettings ts;
  ts.max_depth = 8;
  const auto cases = difftrans::render::hard_cases();
  CHECK(cases.size() >= 8);
  for (const auto& c : cases) {
    CAPTURE(c.name);
    const difftrans::render::HardCaseResult r = difftrans::render::check_hard_case(c, ts);
    CHECK(r.rays == int(c.rays.size()));
    CHECK(r.values == 6 * std::int64_t(c.rays.size()));
    CHECK(r.gradients > 0);
    CHECK(r.nonfinite_values == 0);
    CHECK(r.negative_values == 0);
    CHECK(r.nonfinite_gradients == 0);
    CHECK(r.tape_overflows == 0);
    CHECK(r.clean());
  }
}

TEST_CASE("hard cases: the check counts what is not finite") {
  // the same check must see a NaN when there is one: glass of IoR NaN (the
  // radiance stays finite, its derivatives do not)
  TraceSettings ts;
  ts.max_depth = 8;
  difftrans::render::HardCase c = difftrans::render::hard_cases().front();
  c.ior = std::numeric_limits<float>::quiet_NaN();
  c.rays = {{Vec3f(0.2f, 0.1f, 3), Vec3f(0, 0, -1)}};
  const difftrans::render::HardCaseResult r = difftrans::render::check_hard_case(c, ts);
  MESSAGE("IoR NaN: " << r.nonfinite_values << " of " << r.values << " values, " << r.nonfinite_gradients << " of "
                      << r.gradients << " gradient entries not finite");
  CHECK(r.nonfinite_gradients > 0);
  CHECK_FALSE(r.clean());
}
