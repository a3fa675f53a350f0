// Constants agree with the standard library in every precision.
#include "support/ad_check.hpp"

TEST_CASE("pi and friends") {
  CHECK(difftrans::pi_v<double> == doctest::Approx(std::acos(-1.0)).epsilon(1e-16));
  CHECK(difftrans::pi_v<float> == float(std::acos(-1.0)));
  CHECK(difftrans::two_pi_v<double> == 2 * difftrans::pi_v<double>);
  CHECK(difftrans::inv_pi_v<double> * difftrans::pi_v<double> == doctest::Approx(1.0).epsilon(1e-16));
  CHECK(difftrans::inv_two_pi_v<double> * difftrans::two_pi_v<double> == doctest::Approx(1.0).epsilon(1e-16));
}
