// Platform macros: host compilation sees plain functions.
#include "support/ad_check.hpp"

namespace {
DT_HOST_DEVICE DT_FORCEINLINE int twice(int x) { return 2 * x; }
}  // namespace

TEST_CASE("DT_HOST_DEVICE functions are ordinary functions on the host") {
  CHECK(twice(21) == 42);
  CHECK(DT_DEVICE_PASS == 0);
}
