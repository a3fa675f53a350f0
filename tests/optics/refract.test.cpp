// Reflection and refraction directions: unit length, coplanarity, Snell's
// law, reversibility, eta = 1 (no bending), total internal reflection, hits
// from the back side, and derivatives against finite differences.
#include "support/ad_check.hpp"

using namespace dt_test;
namespace optics = difftrans::optics;

namespace {
Vec3d direction(double theta, double phi) {  // polar angle from +Z
  return Vec3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
}
template <class S> Vec3<S> to(const Vec3d& v) { return Vec3<S>(S(v.x), S(v.y), S(v.z)); }
}  // namespace

TEST_CASE_TEMPLATE("reflect mirrors about the normal", S, DT_ALL_SCALARS) {
  const Vec3<S> n = to<S>(glm::normalize(Vec3d(0.2, 0.3, 1.0)));
  for (double theta : {0.0, 0.4, 1.2, 1.57}) {
    const Vec3<S> wi = to<S>(direction(theta, 0.7));
    const Vec3d wr = to_d(optics::reflect(wi, n));
    const Vec3d wi_d = to_d(wi), n_d = to_d(n);
    CHECK(close(glm::length(wr), 1.0, tol<S>()));
    CHECK(close(glm::dot(wr, n_d), glm::dot(wi_d, n_d), tol<S>()));                 // equal angles
    CHECK(glm::length(glm::cross(wi_d + wr, n_d)) < 10 * tol<S>());                  // wi + wr along n
    CHECK(glm::length(to_d(optics::reflect(optics::reflect(wi, n), n)) - wi_d) < 10 * tol<S>());
  }
}

TEST_CASE_TEMPLATE("refract obeys Snell's law and is reversible", S, DT_ALL_SCALARS) {
  const Vec3d n(0, 0, 1);
  for (double eta : {1.5, 0.8, 2.4}) {
    for (double theta : {0.0, 0.3, 0.7, 1.1, 1.5}) {
      for (double side : {1.0, -1.0}) {
        CAPTURE(eta);
        CAPTURE(theta);
        CAPTURE(side);
        const Vec3d wi = direction(theta, 2.1) * Vec3d(1, 1, side);
        const auto r = optics::refract(to<S>(wi), to<S>(n), S(eta));
        const double eta_it = side > 0 ? eta : 1 / eta;
        const double sin_i = std::sin(theta);
        if (sin_i / eta_it >= 1) {
          CHECK_FALSE(r.valid);
          CHECK(to_d(r.wt) == Vec3d(0, 0, 0));
          continue;
        }
        REQUIRE(r.valid);
        const Vec3d wt = to_d(r.wt);
        CHECK(close(ad::value_of(r.eta_it), eta_it, tol<S>()));
        CHECK(close(glm::length(wt), 1.0, 10 * tol<S>()));
        CHECK(glm::dot(wt, n) * side <= 0);                                      // crosses the surface
        CHECK(std::abs(glm::dot(wt, glm::cross(wi, n))) < 10 * tol<S>());       // plane of incidence
        CHECK(close(glm::length(glm::cross(wt, n)) * eta_it, sin_i, 10 * tol<S>()));  // Snell
        const auto back = optics::refract(r.wt, to<S>(n), S(eta));
        REQUIRE(back.valid);
        CHECK(glm::length(to_d(back.wt) - wi) < 100 * tol<S>());
        // the Fresnel-based overload gives the same direction
        const S cos_i = glm::dot(to<S>(wi), to<S>(n));
        const auto f = optics::fresnel_dielectric(cos_i, S(eta));
        CHECK(glm::length(to_d(optics::refract(to<S>(wi), to<S>(n), cos_i, f)) - wt) < 10 * tol<S>());
      }
    }
  }
}

TEST_CASE_TEMPLATE("eta = 1 does not bend", S, DT_ALL_SCALARS) {
  for (double theta : {0.0, 0.5, 1.4, 1.5707}) {
    const Vec3d wi = direction(theta, 0.3);
    const auto r = optics::refract(to<S>(wi), to<S>(Vec3d(0, 0, 1)), S(1.0));
    REQUIRE(r.valid);
    CHECK(glm::length(to_d(r.wt) + wi) < 1e-6);
  }
}

TEST_CASE_TEMPLATE("derivatives of the refracted direction match finite differences", S, DT_AD_SCALARS) {
  const Vec3d n = glm::normalize(Vec3d(0.1, -0.2, 1.0));
  for (double theta : {0.2, 0.8, 1.2}) {
    for (int comp = 0; comp < 3; ++comp) {
      CAPTURE(theta);
      CAPTURE(comp);
      const auto of_eta = [&](auto e) {
        using U = decltype(e);
        return optics::refract(to<U>(direction(theta, 0.4)), to<U>(n), e).wt[comp];
      };
      const auto of_phi = [&](auto p) {  // rotate wi about +Z
        using U = decltype(p);
        const Vec3<U> wi(U(std::sin(theta)) * cos(p), U(std::sin(theta)) * sin(p), U(std::cos(theta)));
        return optics::refract(wi, to<U>(n), 1.5).wt[comp];
      };
      CHECK(close(derivative<S>(of_eta, 1.5), central_difference(of_eta, 1.5), 200 * tol<S>() + 1e-6));
      CHECK(close(derivative<S>(of_phi, 0.4), central_difference(of_phi, 0.4), 200 * tol<S>() + 1e-6));
    }
  }
}

TEST_CASE_TEMPLATE("grazing and TIR-boundary refraction stays finite", S, DT_AD_SCALARS) {
  const double eta = 1.5, theta_c = std::asin(1 / eta);
  for (double theta : {theta_c - 1e-3, theta_c - 1e-6, theta_c, theta_c + 1e-6}) {
    const auto f = [&](auto e) {
      using U = decltype(e);
      return optics::refract(to<U>(-direction(theta, 0.0)), to<U>(Vec3d(0, 0, 1)), e).wt.x;  // from inside
    };
    double v = 0;
    CHECK(std::isfinite(derivative<S>(f, eta, &v)));
    CHECK(std::isfinite(v));
  }
  const auto grazing = [](auto e) {
    using U = decltype(e);
    return optics::refract(to<U>(direction(1.5707963267948966, 0.0)), to<U>(Vec3d(0, 0, 1)), e).wt.z;
  };
  CHECK(std::isfinite(derivative<S>(grazing, eta)));
}
