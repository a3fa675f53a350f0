// GLM vectors of AD scalars: numeric_limits, and the geometric functions the
// tracer relies on (dot, cross, length, normalize, reflect) differentiated in
// both modes against finite differences.
#include "support/ad_check.hpp"

using namespace dt_test;

TEST_CASE_TEMPLATE("numeric_limits of AD scalars mirror the underlying type", S, DT_AD_SCALARS) {
  using T = ad::scalar_t<S>;
  static_assert(std::numeric_limits<S>::is_specialized);
  static_assert(std::numeric_limits<S>::is_iec559 == std::numeric_limits<T>::is_iec559);
  CHECK(ad::value_of(std::numeric_limits<S>::epsilon()) == std::numeric_limits<T>::epsilon());
  CHECK(ad::value_of(std::numeric_limits<S>::max()) == std::numeric_limits<T>::max());
  CHECK(std::isinf(ad::value_of(std::numeric_limits<S>::infinity())));
}

TEST_CASE_TEMPLATE("geometric functions differentiate correctly", S, DT_AD_SCALARS) {
  const auto f = [](auto t) {
    using U = decltype(t);
    const Vec3<U> a(t, U(0.3) * t, U(1) - t);
    const Vec3<U> b(U(0.2), t * t, U(-0.5));
    const Vec3<U> n = glm::normalize(glm::cross(a, b));
    const Vec3<U> r = glm::reflect(a, n);
    return glm::dot(r, b) + glm::length(a) + glm::distance(a, b);
  };
  for (double x : {0.4, 1.3, -0.8}) {
    CAPTURE(x);
    double v = 0;
    const double d = derivative<S>(f, x, &v);
    CHECK(close(v, f(x), tol<S>()));
    CHECK(close(d, central_difference(f, x), tol<S>() * 50 + 1e-7));
  }
}

TEST_CASE("value_of, detach, lift and all_finite on vectors") {
  using D = ad::Dual<float, 2>;
  const Vec3<D> v(D::variable(1.0f, 0), D(2.0f), D::variable(3.0f, 1));
  const Vec3f p = ad::value_of(v);
  CHECK(p == Vec3f(1, 2, 3));
  const Vec3<D> d = ad::detach(v);
  CHECK(d.x.grad[0] == 0.0f);
  const Vec3<D> l = lift<D>(Vec3f(4, 5, 6));
  CHECK(l.z.value == 6.0f);
  CHECK(all_finite(v));
  Vec3<D> bad = v;
  bad.y.grad[1] = std::numeric_limits<float>::quiet_NaN();
  CHECK_FALSE(all_finite(bad));
}
