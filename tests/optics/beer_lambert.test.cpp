// Beer–Lambert transmittance: closed form and its derivatives, the
// multiplicative property, and huge absorption underflowing cleanly.
#include "support/ad_check.hpp"

using namespace dt_test;
using difftrans::optics::transmittance;

TEST_CASE_TEMPLATE("closed form and derivatives", S, DT_AD_SCALARS) {
  for (double sigma : {0.0, 0.4, 4.0}) {
    for (double d : {0.0, 0.3, 1.7}) {
      double v = 0;
      const double dd = derivative<S>([sigma](auto x) { return transmittance(sigma, x); }, d, &v);
      const double ds = derivative<S>([d](auto s) { return transmittance(s, d); }, sigma);
      CHECK(close(v, std::exp(-sigma * d), tol<S>()));
      CHECK(close(dd, -sigma * std::exp(-sigma * d), 10 * tol<S>()));
      CHECK(close(ds, -d * std::exp(-sigma * d), 10 * tol<S>()));
    }
  }
}

TEST_CASE_TEMPLATE("RGB and the multiplicative property", S, DT_ALL_SCALARS) {
  const Vec3<S> sigma(S(4.0), S(0.4), S(4.0));  // the horse-green absorption
  const Vec3<S> a = transmittance(sigma, S(0.3)), b = transmittance(sigma, S(0.5)), ab = transmittance(sigma, S(0.8));
  for (int c = 0; c < 3; ++c) CHECK(close(ad::value_of(a[c] * b[c]), ad::value_of(ab[c]), tol<S>()));
  CHECK(ad::value_of(a.y) > ad::value_of(a.x));  // green passes
}

TEST_CASE_TEMPLATE("huge absorption underflows to 0 with finite derivatives", S, DT_AD_SCALARS) {
  for (double sigma : {1e3, 1e6, 1e30}) {
    double v = -1;
    const double dd = derivative<S>([sigma](auto x) { return transmittance(sigma, x); }, 2.0, &v);
    const double ds = derivative<S>([](auto s) { return transmittance(s, 2.0); }, sigma);
    CHECK(v == 0.0);
    CHECK(dd == 0.0);
    CHECK(ds == 0.0);
  }
  // zero distance through huge absorption: nothing absorbed, gradient -d T = 0 in sigma
  double v = 0;
  CHECK(derivative<S>([](auto s) { return transmittance(s, 0.0); }, 1e30, &v) == 0.0);
  CHECK(v == 1.0);
}
