// Test helpers for derivatives: one body, written once, evaluates df/dx with
// any AD scalar (Dual seeds lane 0, Var records on a tape) and with central
// finite differences in double.
#pragma once

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "difftrans/difftrans.hpp"

namespace dt_test {

using namespace difftrans;

// The AD scalars every derivative test runs over.
#define DT_AD_SCALARS                                                                          \
  difftrans::ad::Dual<double, 1>, difftrans::ad::Dual<double, 3>, difftrans::ad::Var<double>, \
      difftrans::ad::Dual<float, 1>, difftrans::ad::Var<float>
// Every scalar of the generic path.
#define DT_ALL_SCALARS float, double, DT_AD_SCALARS

// Tolerance suited to the precision of S.
template <class S> constexpr double tol() { return std::is_same_v<ad::scalar_t<S>, float> ? 2e-4 : 1e-9; }

// Central finite difference of f at x in double, with a step scaled to x.
template <class F>
double central_difference(F&& f, double x, double h = 1e-6) {
  const double step = h * std::max(1.0, std::abs(x));
  return (double(f(x + step)) - double(f(x - step))) / (2.0 * step);
}

// df/dx at x, evaluated with scalar S; also returns the value through *value.
template <class S, class F>
double derivative(F&& f, double x, double* value = nullptr) {
  using T = ad::scalar_t<S>;
  if constexpr (ad::is_dual_v<S>) {
    S v = S::variable(T(x), 0);
    for (int i = 1; i < S::lanes; ++i) v.grad[i] = T(i + 1);  // other lanes carry other seeds
    const S y = f(v);
    for (int i = 1; i < S::lanes; ++i) {
      if (std::isfinite(double(y.grad[0])))
        CHECK(double(y.grad[i]) == doctest::Approx(double(y.grad[0]) * (i + 1)).epsilon(1e-5));
      else
        CHECK(double(y.grad[i]) == double(y.grad[0]));
    }
    if (value) *value = double(y.value);
    return double(y.grad[0]);
  } else {
    ad::Tape<T> tape(1 << 12);
    const S v = tape.variable(T(x));
    const S y = f(v);
    REQUIRE_FALSE(tape.overflowed());
    tape.backward(y);
    if (value) *value = double(y.value);
    return double(tape.adjoint(v));
  }
}

// The value of a vector of any scalar, in double.
template <class V> Vec3d to_d(const V& v) { return Vec3d(ad::value_of(v)); }

// Relative-or-absolute closeness.
inline bool close(double a, double b, double rel) {
  return std::abs(a - b) <= rel * std::max(1.0, std::max(std::abs(a), std::abs(b)));
}

// |a − b| / |b| over two arrays of the same length (L2 norms, in double).
inline double relative_l2(const std::vector<float>& a, const std::vector<float>& b) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    den += double(b[i]) * b[i];
  }
  return std::sqrt(num / std::max(den, 1e-30));
}

}  // namespace dt_test

namespace doctest {
// Vectors print as (x, y, z) in failure messages.
template <glm::length_t L, class T, glm::qualifier Q>
struct StringMaker<glm::vec<L, T, Q>> {
  static String convert(const glm::vec<L, T, Q>& v) {
    std::string s = "(";
    for (glm::length_t i = 0; i < L; ++i) s += (i ? ", " : "") + std::to_string(double(difftrans::ad::value_of(v[i])));
    return String((s + ")").c_str());
  }
};
}  // namespace doctest
