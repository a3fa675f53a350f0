// Forward-mode automatic differentiation: Dual<T, N> carries a value and N
// tangent lanes. Trivially copyable and usable in device code. Arithmetic
// operators and math functions live in ad/math.hpp.
#pragma once

#include <type_traits>

#include "difftrans/ad/traits.hpp"

namespace difftrans::ad {

template <class T, int N>
struct Dual {
  static_assert(std::is_floating_point_v<T>, "Dual<T, N>: T must be float or double");
  static_assert(N >= 1, "Dual<T, N>: N must be at least 1");
  using value_type = T;
  static constexpr int lanes = N;

  T value;
  T grad[N];

  Dual() = default;  // trivial: uninitialized, like float
  template <class U, std::enable_if_t<std::is_arithmetic_v<U>, int> = 0>
  DT_HOST_DEVICE constexpr Dual(U v) : value(T(v)), grad{} {}

  // A variable seeded with a unit tangent on one lane.
  DT_HOST_DEVICE static constexpr Dual variable(T v, int lane) {
    Dual d(v);
    d.grad[lane] = T(1);
    return d;
  }

  template <class U>
  DT_HOST_DEVICE Dual& operator+=(const U& o) { return *this = *this + o; }
  template <class U>
  DT_HOST_DEVICE Dual& operator-=(const U& o) { return *this = *this - o; }
  template <class U>
  DT_HOST_DEVICE Dual& operator*=(const U& o) { return *this = *this * o; }
  template <class U>
  DT_HOST_DEVICE Dual& operator/=(const U& o) { return *this = *this / o; }
};

template <class T, int N>
DT_HOST_DEVICE constexpr T value_of(const Dual<T, N>& x) { return x.value; }

template <class T, int N>
DT_HOST_DEVICE constexpr Dual<T, N> detach(const Dual<T, N>& x) { return Dual<T, N>(x.value); }

namespace detail {

// The two primitives every derivative rule of math.hpp is written with.
// unary: result value v, partial derivative dx with respect to x.
template <class T, int N>
DT_HOST_DEVICE DT_FORCEINLINE Dual<T, N> unary(const Dual<T, N>& x, T v, T dx) {
  Dual<T, N> r;
  r.value = v;
  for (int i = 0; i < N; ++i) r.grad[i] = dx * x.grad[i];
  return r;
}

// binary: result value v, partials da and db with respect to a and b.
template <class T, int N>
DT_HOST_DEVICE DT_FORCEINLINE Dual<T, N> binary(const Dual<T, N>& a, const Dual<T, N>& b, T v, T da, T db) {
  Dual<T, N> r;
  r.value = v;
  for (int i = 0; i < N; ++i) r.grad[i] = da * a.grad[i] + db * b.grad[i];
  return r;
}

}  // namespace detail
}  // namespace difftrans::ad
