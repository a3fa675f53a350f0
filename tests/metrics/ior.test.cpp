// IoR error: |eta_predicted - eta_true|.
#include "difftrans/metrics/ior.hpp"

#include <doctest/doctest.h>

TEST_CASE("IoR error is the absolute difference") {
  CHECK(difftrans::metrics::ior_error(1.5, 1.472) == doctest::Approx(0.028));
  CHECK(difftrans::metrics::ior_error(1.4, 1.45) == doctest::Approx(0.05));
  CHECK(difftrans::metrics::ior_error(1.6, 1.6) == 0.0);
}
