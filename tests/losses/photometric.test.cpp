// Colour and tone terms of stage 2: values by hand, derivatives against
// central differences.
#include <doctest/doctest.h>

#include <cmath>
#include <initializer_list>

#include "difftrans/losses/photometric.hpp"

using difftrans::Vec3f;
namespace losses = difftrans::losses;

TEST_CASE("photometric: L2, relative L2 and tone with their derivatives") {
  const Vec3f r(0.6f, 0.3f, 0.2f), c(0.5f, 0.4f, 0.1f);
  using K = losses::ColourLoss;
  const losses::RayColourLoss l = losses::ray_colour_loss(r, c, K::l2, true);
  CHECK(l.colour == doctest::Approx(0.01 + 0.01 + 0.01).epsilon(1e-5));
  CHECK(l.dcolour.x == doctest::Approx(0.2f));
  const float h = 1e-3f;
  for (int k = 0; k < 3; ++k)
    for (K kind : {K::l2, K::relative_l2, K::log_l2}) {
      Vec3f a = r, b = r;
      a[k] += h, b[k] -= h;
      const auto la = losses::ray_colour_loss(a, c, kind, true), lb = losses::ray_colour_loss(b, c, kind, true);
      const auto l0 = losses::ray_colour_loss(r, c, kind, true);
      CHECK(l0.dtone[k] == doctest::Approx((la.tone - lb.tone) / (2 * h)).epsilon(2e-2));
      // relative L2 holds its denominator constant: its derivative is not the full one
      if (kind != K::relative_l2) CHECK(l0.dcolour[k] == doctest::Approx((la.colour - lb.colour) / (2 * h)).epsilon(1e-2));
    }
  CHECK(losses::ray_colour_loss(2.0f * c, c, K::l2, true).tone == doctest::Approx(0.0).epsilon(1e-6));
  const losses::RayColourLoss off = losses::ray_colour_loss(r, c, K::l2, false);
  CHECK(off.tone == 0.0);
  CHECK(off.dtone == Vec3f(0.0f));
}

TEST_CASE("photometric: log L2 is bounded for HDR outliers and zero at the target") {
  using K = losses::ColourLoss;
  const Vec3f c(0.5f, 0.4f, 0.1f), sun(6500.0f, 6000.0f, 5000.0f);
  const auto same = losses::ray_colour_loss(c, c, K::log_l2, false);
  CHECK(same.colour == doctest::Approx(0.0));
  CHECK(same.dcolour == Vec3f(0.0f));
  const auto l = losses::ray_colour_loss(sun, c, K::log_l2, false), p = losses::ray_colour_loss(sun, c, K::l2, false);
  CHECK(l.colour < 3.0 * 9.0 * 9.0);  // log(1 + 6500) < 9 per channel
  CHECK(p.colour > 1e7);
  CHECK(l.dcolour.x < 2.0f * 9.0f / 6501.0f);
  CHECK(losses::ray_colour_loss(Vec3f(2.0f, 0.4f, 0.1f), c, K::log_l2, false).colour ==
        doctest::Approx(std::log(3.0 / 1.5) * std::log(3.0 / 1.5)).epsilon(1e-5));
}
