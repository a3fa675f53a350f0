// Colour and tone terms of stage 2: values by hand, derivatives against
// central differences.
#include <doctest/doctest.h>

#include <initializer_list>

#include "difftrans/losses/photometric.hpp"

using difftrans::Vec3f;
namespace losses = difftrans::losses;

TEST_CASE("photometric: L2, relative L2 and tone with their derivatives") {
  const Vec3f r(0.6f, 0.3f, 0.2f), c(0.5f, 0.4f, 0.1f);
  const losses::RayColourLoss l = losses::ray_colour_loss(r, c, false, true);
  CHECK(l.colour == doctest::Approx(0.01 + 0.01 + 0.01).epsilon(1e-5));
  CHECK(l.dcolour.x == doctest::Approx(0.2f));
  const float h = 1e-3f;
  for (int k = 0; k < 3; ++k)
    for (bool relative : {false, true}) {
      Vec3f a = r, b = r;
      a[k] += h, b[k] -= h;
      const auto la = losses::ray_colour_loss(a, c, relative, true), lb = losses::ray_colour_loss(b, c, relative, true);
      const auto l0 = losses::ray_colour_loss(r, c, relative, true);
      CHECK(l0.dtone[k] == doctest::Approx((la.tone - lb.tone) / (2 * h)).epsilon(2e-2));
      if (!relative) CHECK(l0.dcolour[k] == doctest::Approx((la.colour - lb.colour) / (2 * h)).epsilon(1e-2));
    }
  CHECK(losses::ray_colour_loss(2.0f * c, c, false, true).tone == doctest::Approx(0.0).epsilon(1e-6));
  const losses::RayColourLoss off = losses::ray_colour_loss(r, c, false, false);
  CHECK(off.tone == 0.0);
  CHECK(off.dtone == Vec3f(0.0f));
}
