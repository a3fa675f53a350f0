// Fresnel reflectance against closed forms and identities — normal incidence,
// Snell's law, energy R + T = 1 with an independent transmittance formula,
// reciprocity — and the hard cases: grazing incidence, the TIR boundary from
// both sides, eta = 1, eta < 1, denormal cosines, and a dense sweep in which
// every value and derivative must be finite.
#include "support/ad_check.hpp"

using namespace dt_test;
using difftrans::optics::fresnel_dielectric;

namespace {
// Transmittance from the Fresnel transmission amplitudes (Born & Wolf), in
// double: an independent route to 1 − R.
double transmittance_from_amplitudes(double cos_i, double eta) {
  const double sin2_t = (1 - cos_i * cos_i) / (eta * eta);
  const double cos_t = std::sqrt(1 - sin2_t);
  const double ts = 2 * cos_i / (cos_i + eta * cos_t);
  const double tp = 2 * cos_i / (eta * cos_i + cos_t);
  return eta * cos_t / cos_i * 0.5 * (ts * ts + tp * tp);
}
}  // namespace

TEST_CASE_TEMPLATE("normal incidence: R = ((eta - 1) / (eta + 1))^2 from both sides", S, DT_ALL_SCALARS) {
  for (double eta : {1.1, 1.333, 1.5, 2.42, 0.75}) {
    CAPTURE(eta);
    const double expected = std::pow((eta - 1) / (eta + 1), 2);
    const auto front = fresnel_dielectric(S(1.0), S(eta));
    const auto back = fresnel_dielectric(S(-1.0), S(eta));
    CHECK(close(ad::value_of(front.R), expected, tol<S>()));
    CHECK(close(ad::value_of(back.R), expected, tol<S>()));
    CHECK(ad::value_of(front.cos_theta_t) == doctest::Approx(-1.0));
    CHECK(ad::value_of(back.cos_theta_t) == doctest::Approx(1.0));
    CHECK_FALSE(front.tir);
    CHECK(close(ad::value_of(back.eta_it), 1 / eta, tol<S>()));
  }
}

TEST_CASE_TEMPLATE("Snell's law, energy conservation and reciprocity", S, DT_ALL_SCALARS) {
  for (double eta : {1.2, 1.5, 2.0, 0.8}) {
    for (int k = 1; k < 40; ++k) {
      const double cos_i = k / 40.0;
      CAPTURE(eta);
      CAPTURE(cos_i);
      const auto f = fresnel_dielectric(S(cos_i), S(eta));
      const double sin_i = std::sqrt(1 - cos_i * cos_i);
      if (std::abs(sin_i / eta - 1) < 1e-6) continue;  // exactly critical: either answer is right
      if (sin_i / eta > 1) {
        CHECK(f.tir);
        CHECK(ad::value_of(f.R) == 1.0);
        continue;
      }
      REQUIRE_FALSE(f.tir);
      const double cos_t = ad::value_of(f.cos_theta_t);
      CHECK(cos_t < 0);  // signed opposite to cos_i
      CHECK(close(std::sqrt(1 - cos_t * cos_t) * eta, sin_i, tol<S>() * 10));
      const double R = ad::value_of(f.R);
      CHECK(R >= 0.0);
      CHECK(R <= 1.0);
      CHECK(close(R + transmittance_from_amplitudes(cos_i, eta), 1.0, tol<S>() * 10));
      // light going back along the transmitted direction sees the same R
      const auto g = fresnel_dielectric(S(-cos_t), S(1 / eta));
      CHECK(close(ad::value_of(g.R), R, tol<S>() * 10));
      // and arriving from the back side is the same as inverting eta
      const auto h = fresnel_dielectric(S(cos_t), S(eta));
      CHECK(close(ad::value_of(h.R), ad::value_of(g.R), tol<S>()));
    }
  }
}

TEST_CASE_TEMPLATE("eta = 1: no interface", S, DT_ALL_SCALARS) {
  for (double c : {1.0, 0.5, 1e-3, 0.0, -0.3, -1.0}) {
    CAPTURE(c);
    const auto f = fresnel_dielectric(S(c), S(1.0));
    CHECK(ad::value_of(f.R) == 0.0);
    CHECK_FALSE(f.tir);
    CHECK(std::abs(ad::value_of(f.cos_theta_t) + c) < 1e-6);
  }
}

TEST_CASE_TEMPLATE("grazing incidence: R -> 1 continuously, finite derivatives", S, DT_AD_SCALARS) {
  for (double eta : {1.5, 1.01}) {
    double previous = 0;
    for (double c : {1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 0.0}) {
      CAPTURE(eta);
      CAPTURE(c);
      double R = 0;
      const double dc = derivative<S>([eta](auto x) { return fresnel_dielectric(x, eta).R; }, c, &R);
      const double de = derivative<S>([c](auto e) { return fresnel_dielectric(c, e).R; }, eta);
      CHECK(std::isfinite(dc));
      CHECK(std::isfinite(de));
      CHECK(R >= previous);
      CHECK(R <= 1.0);
      previous = R;
    }
    CHECK(previous == doctest::Approx(1.0));
  }
}

TEST_CASE_TEMPLATE("TIR boundary approached from both sides", S, DT_AD_SCALARS) {
  // Inside glass (eta = 1.5 seen from the back: cos_i < 0, relative 1/1.5).
  const double eta = 1.5, cos_c = std::sqrt(1 - 1 / (eta * eta));
  std::vector<double> gap_over_sqrt;
  for (double delta : {1e-2, 1e-3, 1e-4, 1e-5, 1e-6}) {
    for (double side : {-1.0, 1.0}) {
      const double c = -(cos_c + side * delta);  // side +1: steeper (transmits); -1: past critical
      CAPTURE(delta);
      CAPTURE(side);
      const auto f = fresnel_dielectric(S(c), S(eta));
      CHECK(f.tir == (side < 0));
      double R = 0;
      const double dc = derivative<S>([eta](auto x) { return fresnel_dielectric(x, eta).R; }, c, &R);
      const double de = derivative<S>([c](auto e) { return fresnel_dielectric(c, e).R; }, eta);
      const double dct = derivative<S>([eta](auto x) { return fresnel_dielectric(x, eta).cos_theta_t; }, c);
      CHECK(std::isfinite(dc));
      CHECK(std::isfinite(de));
      CHECK(std::isfinite(dct));
      if (side < 0) CHECK(R == 1.0);
      if (side > 0) gap_over_sqrt.push_back((1 - R) / std::sqrt(delta));
    }
  }
  // continuous at the boundary: 1 − R vanishes like sqrt(distance to critical)
  for (std::size_t k = 2; k < gap_over_sqrt.size(); ++k)  // asymptotic from delta = 1e-3 on
    CHECK(gap_over_sqrt[k] == doctest::Approx(gap_over_sqrt[k - 1]).epsilon(0.2));
}

TEST_CASE_TEMPLATE("derivatives match finite differences", S, DT_AD_SCALARS) {
  for (double eta : {1.33, 1.5, 2.2, 0.9}) {
    for (double c : {0.95, 0.6, 0.2, -0.3, -0.9}) {
      const double sin_t = std::sqrt(1 - c * c) * (c > 0 ? 1 / eta : eta);
      if (sin_t > 0.98) continue;  // stay clear of the kink at the TIR boundary
      CAPTURE(eta);
      CAPTURE(c);
      const auto R_of_c = [eta](auto x) { return fresnel_dielectric(x, eta).R; };
      const auto R_of_eta = [c](auto e) { return fresnel_dielectric(c, e).R; };
      const auto ct_of_eta = [c](auto e) { return fresnel_dielectric(c, e).cos_theta_t; };
      CHECK(close(derivative<S>(R_of_c, c), central_difference(R_of_c, c), tol<S>() * 100 + 1e-6));
      CHECK(close(derivative<S>(R_of_eta, eta), central_difference(R_of_eta, eta), tol<S>() * 100 + 1e-6));
      CHECK(close(derivative<S>(ct_of_eta, eta), central_difference(ct_of_eta, eta), tol<S>() * 100 + 1e-6));
    }
  }
}

TEST_CASE_TEMPLATE("dense sweep: every value and derivative finite, R in [0, 1]", S, DT_AD_SCALARS) {
  using T = ad::scalar_t<S>;
  const T denormal = std::numeric_limits<T>::denorm_min() * T(7);
  std::vector<double> cosines;
  for (int k = -1000; k <= 1000; ++k) cosines.push_back(k / 1000.0);
  for (double tiny : {double(denormal), 1e-30, 1e-12, 1 - 1e-12, 1.0 + 1e-7})
    for (double sign : {-1.0, 1.0}) cosines.push_back(sign * tiny);
  int bad = 0;
  for (double eta : {0.5, 0.9, 1.0, 1.0001, 1.1, 1.5, 2.5, 10.0}) {
    for (double c : cosines) {
      double R = 0;
      const double dc = derivative<S>([eta](auto x) { return fresnel_dielectric(x, eta).R; }, c, &R);
      const double de = derivative<S>([c](auto e) { return fresnel_dielectric(c, e).R; }, eta);
      double ct = 0;
      const double dct = derivative<S>([c](auto e) { return fresnel_dielectric(c, e).cos_theta_t; }, eta, &ct);
      const bool ok = std::isfinite(R) && std::isfinite(dc) && std::isfinite(de) && std::isfinite(ct) &&
                      std::isfinite(dct) && R >= 0 && R <= 1 && std::abs(ct) <= 1;
      if (!ok) {
        ++bad;
        MESSAGE("eta " << eta << " cos " << c << ": R " << R << " dR/dc " << dc << " dR/deta " << de << " cos_t " << ct);
      }
    }
  }
  CHECK(bad == 0);
}
