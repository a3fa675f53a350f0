// Arithmetic and math functions for every scalar of the generic path: plain
// float/double and the AD types. Each derivative rule is written once, on the
// primitives detail::unary / detail::binary, and serves Dual and Var alike.
// Call these unqualified from generic code (they are also visible in
// namespace difftrans). Non-smooth points get a defined, finite derivative.
#pragma once

#include <cmath>
#include <limits>

#include "difftrans/ad/dual.hpp"
#include "difftrans/ad/tape.hpp"

namespace difftrans::ad {

// Smallest argument at which safe_sqrt (and the asin/acos rules) evaluate
// their derivative: keeps d sqrt(x)/dx finite at x = 0 (at most 5e4). The
// same in every precision, so float and double passes share one derivative
// rule and differ only by rounding.
template <class T> inline constexpr T safe_sqrt_eps = T(1e-10);

namespace detail {

template <class S> using enable_ad_t = std::enable_if_t<is_ad_v<S>, int>;
template <class T> using enable_plain_t = std::enable_if_t<std::is_floating_point_v<T>, int>;

// Combines a mixed (A, B) pair into the AD result: a constant side gets no node.
template <class A, class B, class T>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<A, B> apply2(const A& a, const B& b, T v, T da, T db) {
  if constexpr (is_ad_v<A> && is_ad_v<B>) {
    return binary(a, b, v, da, db);
  } else if constexpr (is_ad_v<A>) {
    return unary(a, v, da);
  } else {
    return unary(b, v, db);
  }
}

}  // namespace detail

// ---------------------------------------------------------------- arithmetic

template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<A, B> operator+(const A& a, const B& b) {
  using T = scalar_t<promote_t<A, B>>;
  return detail::apply2(a, b, T(value_of(a) + value_of(b)), T(1), T(1));  // d(a+b) = da + db
}

template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<A, B> operator-(const A& a, const B& b) {
  using T = scalar_t<promote_t<A, B>>;
  return detail::apply2(a, b, T(value_of(a) - value_of(b)), T(1), T(-1));  // d(a-b) = da - db
}

template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<A, B> operator*(const A& a, const B& b) {
  using T = scalar_t<promote_t<A, B>>;
  const T va = T(value_of(a)), vb = T(value_of(b));
  return detail::apply2(a, b, va * vb, vb, va);  // d(ab) = b da + a db
}

template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<A, B> operator/(const A& a, const B& b) {
  using T = scalar_t<promote_t<A, B>>;
  // the value is a / b exactly as plain arithmetic computes it, so that
  // decisions on values are identical for every scalar type
  const T vb = T(value_of(b)), v = T(value_of(a)) / vb, inv = T(1) / vb;
  return detail::apply2(a, b, v, inv, -v * inv);  // d(a/b) = da / b - (a / b²) db
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE DT_FORCEINLINE S operator-(const S& x) {
  using T = scalar_t<S>;
  return detail::unary(x, -value_of(x), T(-1));  // d(-x) = -dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE DT_FORCEINLINE S operator+(const S& x) { return x; }

// Comparisons look at values only: discrete decisions are the same for every scalar.
template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE constexpr bool operator<(const A& a, const B& b) { return value_of(a) < value_of(b); }
template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE constexpr bool operator<=(const A& a, const B& b) { return value_of(a) <= value_of(b); }
template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE constexpr bool operator>(const A& a, const B& b) { return value_of(a) > value_of(b); }
template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE constexpr bool operator>=(const A& a, const B& b) { return value_of(a) >= value_of(b); }
template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE constexpr bool operator==(const A& a, const B& b) { return value_of(a) == value_of(b); }
template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE constexpr bool operator!=(const A& a, const B& b) { return value_of(a) != value_of(b); }

// ------------------------------------------------------- plain float/double

template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T sqrt(T x) { return std::sqrt(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T exp(T x) { return std::exp(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T expm1(T x) { return std::expm1(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T log(T x) { return std::log(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T log1p(T x) { return std::log1p(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T sin(T x) { return std::sin(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T cos(T x) { return std::cos(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T tan(T x) { return std::tan(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T asin(T x) { return std::asin(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T acos(T x) { return std::acos(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T atan(T x) { return std::atan(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T tanh(T x) { return std::tanh(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T abs(T x) { return std::fabs(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T floor(T x) { return std::floor(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T ceil(T x) { return std::ceil(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE T safe_sqrt(T x) { return std::sqrt(x > T(0) ? x : T(0)); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE constexpr T square(T x) { return x * x; }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE bool isfinite(T x) { return std::isfinite(x); }
template <class T, detail::enable_plain_t<T> = 0> DT_HOST_DEVICE bool isnan(T x) { return std::isnan(x); }
template <class T, detail::enable_plain_t<T> = 0>
DT_HOST_DEVICE T sigmoid(T x) {  // stable for large |x|
  if (x >= T(0)) return T(1) / (T(1) + std::exp(-x));
  const T e = std::exp(x);
  return e / (T(1) + e);
}
template <class T, detail::enable_plain_t<T> = 0>
DT_HOST_DEVICE T softplus(T x) {  // log(1 + e^x) = max(x, 0) + log1p(e^-|x|)
  return (x > T(0) ? x : T(0)) + std::log1p(std::exp(-std::fabs(x)));
}
template <class A, class B, std::enable_if_t<is_plain_v<A> && is_plain_v<B>, int> = 0>
DT_HOST_DEVICE promote_t<A, B> pow(A x, B y) {
  using T = promote_t<A, B>;
  return std::pow(T(x), T(y));
}
template <class A, class B, std::enable_if_t<is_plain_v<A> && is_plain_v<B>, int> = 0>
DT_HOST_DEVICE promote_t<A, B> atan2(A y, B x) {
  using T = promote_t<A, B>;
  return std::atan2(T(y), T(x));
}

// ------------------------------------------------------- derivative rules

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S sqrt(const S& x) {
  using T = scalar_t<S>;
  const T v = sqrt(value_of(x));
  return detail::unary(x, v, T(0.5) / v);  // d sqrt(x) = dx / (2 sqrt(x)); infinite at 0
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S safe_sqrt(const S& x) {
  using T = scalar_t<S>;
  const T xv = value_of(x);
  const T v = sqrt(xv > T(0) ? xv : T(0));
  // d sqrt(x) = dx / (2 sqrt(max(x, eps))): finite at and below 0
  return detail::unary(x, v, T(0.5) / sqrt(xv > safe_sqrt_eps<T> ? xv : safe_sqrt_eps<T>));
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S square(const S& x) {
  using T = scalar_t<S>;
  const T v = value_of(x);
  return detail::unary(x, v * v, T(2) * v);  // d x² = 2x dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S exp(const S& x) {
  const auto v = exp(value_of(x));
  return detail::unary(x, v, v);  // d e^x = e^x dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S expm1(const S& x) {
  const auto xv = value_of(x);
  return detail::unary(x, expm1(xv), exp(xv));  // d (e^x - 1) = e^x dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S log(const S& x) {
  using T = scalar_t<S>;
  const T xv = value_of(x);
  return detail::unary(x, log(xv), T(1) / xv);  // d log x = dx / x
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S log1p(const S& x) {
  using T = scalar_t<S>;
  const T xv = value_of(x);
  return detail::unary(x, log1p(xv), T(1) / (T(1) + xv));  // d log(1+x) = dx / (1+x)
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S sin(const S& x) {
  const auto xv = value_of(x);
  return detail::unary(x, sin(xv), cos(xv));  // d sin x = cos x dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S cos(const S& x) {
  const auto xv = value_of(x);
  return detail::unary(x, cos(xv), -sin(xv));  // d cos x = -sin x dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S tan(const S& x) {
  using T = scalar_t<S>;
  const T v = tan(value_of(x));
  return detail::unary(x, v, T(1) + v * v);  // d tan x = (1 + tan² x) dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S asin(const S& x) {
  using T = scalar_t<S>;
  const T xv = value_of(x), c = T(1) - xv * xv;
  // d asin x = dx / sqrt(1 - x²), with 1 - x² clamped at eps: finite at ±1
  return detail::unary(x, asin(xv), T(1) / sqrt(c > safe_sqrt_eps<T> ? c : safe_sqrt_eps<T>));
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S acos(const S& x) {
  using T = scalar_t<S>;
  const T xv = value_of(x), c = T(1) - xv * xv;
  // d acos x = -dx / sqrt(1 - x²), with 1 - x² clamped at eps: finite at ±1
  return detail::unary(x, acos(xv), T(-1) / sqrt(c > safe_sqrt_eps<T> ? c : safe_sqrt_eps<T>));
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S atan(const S& x) {
  using T = scalar_t<S>;
  const T xv = value_of(x);
  return detail::unary(x, atan(xv), T(1) / (T(1) + xv * xv));  // d atan x = dx / (1 + x²)
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S tanh(const S& x) {
  using T = scalar_t<S>;
  const T v = tanh(value_of(x));
  return detail::unary(x, v, T(1) - v * v);  // d tanh x = (1 - tanh² x) dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S sigmoid(const S& x) {
  using T = scalar_t<S>;
  const T v = sigmoid(value_of(x));
  return detail::unary(x, v, v * (T(1) - v));  // d σ(x) = σ(x) (1 - σ(x)) dx
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S softplus(const S& x) {
  const auto xv = value_of(x);
  return detail::unary(x, softplus(xv), sigmoid(xv));  // d log(1 + e^x) = σ(x) dx
}

// A unary function of x whose value v and slope dv/dx at x's value are looked
// up rather than evaluated (a table of the function over the parameters x is
// read from): for the AD types a node with that value and partial; for a plain
// scalar the value alone. It gives the same bits as evaluating the function
// in the pass when the table holds that function's values in the pass's
// precision.
template <class T, detail::enable_plain_t<T> = 0>
DT_HOST_DEVICE DT_FORCEINLINE T known_unary(T /*x*/, T v, T /*slope*/) {
  return v;
}
template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE DT_FORCEINLINE S known_unary(const S& x, scalar_t<S> v, scalar_t<S> slope) {
  return detail::unary(x, v, slope);
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE S abs(const S& x) {
  using T = scalar_t<S>;
  const T xv = value_of(x);
  // d |x| = sign(x) dx, with sign(0) = 0
  return detail::unary(x, abs(xv), xv > T(0) ? T(1) : (xv < T(0) ? T(-1) : T(0)));
}

template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE promote_t<A, B> pow(const A& x, const B& y) {
  using T = scalar_t<promote_t<A, B>>;
  const T xv = T(value_of(x)), yv = T(value_of(y)), v = pow(xv, yv);
  // d x^y = y x^(y-1) dx + log(x) x^y dy; the dy term is 0 where x^y = 0 or x <= 0
  const T dx = yv == T(0) ? T(0) : yv * pow(xv, yv - T(1));
  const T dy = (xv > T(0) && v != T(0)) ? log(xv) * v : T(0);
  return detail::apply2(x, y, v, dx, dy);
}

template <class A, class B, enable_if_ad_pair_t<A, B> = 0>
DT_HOST_DEVICE promote_t<A, B> atan2(const A& y, const B& x) {
  using T = scalar_t<promote_t<A, B>>;
  const T yv = T(value_of(y)), xv = T(value_of(x)), r2 = xv * xv + yv * yv;
  const T inv = r2 > T(0) ? T(1) / r2 : T(0);
  // d atan2(y, x) = (x dy - y dx) / (x² + y²); 0 at the origin
  return detail::apply2(y, x, atan2(yv, xv), xv * inv, -yv * inv);
}

// ------------------------------------------------ selection (no new nodes)
// The derivative follows whichever argument is chosen by value.

template <class A, class B, enable_if_scalar_pair_t<A, B> = 0>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<A, B> select(bool c, const A& a, const B& b) {
  using R = promote_t<A, B>;
  return c ? R(a) : R(b);
}

template <class A, class B, enable_if_scalar_pair_t<A, B> = 0>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<A, B> min(const A& a, const B& b) {
  return select(value_of(b) < value_of(a), b, a);  // ties pick a
}

template <class A, class B, enable_if_scalar_pair_t<A, B> = 0>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<A, B> max(const A& a, const B& b) {
  return select(value_of(a) < value_of(b), b, a);  // ties pick a
}

template <class X, class L, class H,
          std::enable_if_t<is_scalar_pair<X, L>::value && is_scalar_pair<X, H>::value, int> = 0>
DT_HOST_DEVICE DT_FORCEINLINE promote_t<promote_t<X, L>, H> clamp(const X& x, const L& lo, const H& hi) {
  using R = promote_t<promote_t<X, L>, H>;
  // d clamp = dx inside [lo, hi], d lo below, d hi above
  return value_of(x) < value_of(lo) ? R(lo) : (value_of(hi) < value_of(x) ? R(hi) : R(x));
}

template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE bool isfinite(const S& x) { return isfinite(value_of(x)); }
template <class S, detail::enable_ad_t<S> = 0>
DT_HOST_DEVICE bool isnan(const S& x) { return isnan(value_of(x)); }

// True when the value and every tangent lane are finite (Var: the value).
template <class S>
DT_HOST_DEVICE bool all_finite(const S& x) {
  if constexpr (is_dual_v<S>) {
    bool ok = isfinite(x.value);
    for (int i = 0; i < S::lanes; ++i) ok = ok && isfinite(x.grad[i]);
    return ok;
  } else {
    return isfinite(value_of(x));
  }
}

}  // namespace difftrans::ad

namespace difftrans {
// Generic code anywhere under difftrans:: calls these unqualified.
using ad::abs;
using ad::acos;
using ad::all_finite;
using ad::asin;
using ad::atan;
using ad::atan2;
using ad::ceil;
using ad::clamp;
using ad::cos;
using ad::exp;
using ad::expm1;
using ad::floor;
using ad::isfinite;
using ad::isnan;
using ad::log;
using ad::log1p;
using ad::max;
using ad::min;
using ad::pow;
using ad::safe_sqrt;
using ad::select;
using ad::sigmoid;
using ad::sin;
using ad::softplus;
using ad::sqrt;
using ad::square;
using ad::tan;
using ad::tanh;
using ad::value_of;
using ad::detach;
}  // namespace difftrans
