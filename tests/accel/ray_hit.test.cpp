// The shared hit record: a default hit is a miss at infinity.
#include "support/ad_check.hpp"

#include "difftrans/accel/ray_hit.hpp"

TEST_CASE("a default RayHit is a miss") {
  const difftrans::accel::RayHit h;
  CHECK_FALSE(h.hit());
  CHECK(std::isinf(h.t));
  difftrans::accel::RayHit g;
  g.prim = 0;
  CHECK(g.hit());
}
