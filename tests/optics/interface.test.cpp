// Interface events: weights sum to one, TIR sends everything to reflection,
// and the directions agree with reflect / refract.
#include "support/ad_check.hpp"

using namespace dt_test;
namespace optics = difftrans::optics;

TEST_CASE_TEMPLATE("interface event", S, DT_ALL_SCALARS) {
  const Vec3<S> n(S(0), S(0), S(1));
  for (double z : {0.9, 0.3, -0.3, -0.9}) {
    const double s = std::sqrt(1 - z * z);
    const Vec3<S> wi(S(s), S(0), S(z));
    const auto e = optics::interface_event(wi, n, 1.5);
    CHECK(close(ad::value_of(e.R + e.T), 1.0, tol<S>()));
    CHECK(glm::length(ad::value_of(e.wr - optics::reflect(wi, n))) < tol<S>());
    const auto r = optics::refract(wi, n, S(1.5));
    CHECK(e.tir == !r.valid);
    CHECK(glm::length(ad::value_of(e.wt - r.wt)) < tol<S>());
    if (e.tir) {
      CHECK(ad::value_of(e.T) == 0.0);
      CHECK(z < 0);
    }
  }
}
