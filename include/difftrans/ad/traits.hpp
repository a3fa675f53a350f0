// Traits over scalar types: which ones carry derivatives, their underlying
// floating-point type, value_of / detach, and the result type of mixed
// expressions. Specialized by dual.hpp and tape.hpp.
#pragma once

#include <type_traits>

#include "difftrans/core/platform.hpp"

namespace difftrans::ad {

template <class T, int N> struct Dual;
template <class T> struct Var;
template <class T> class Tape;

template <class S> struct is_dual : std::false_type {};
template <class T, int N> struct is_dual<Dual<T, N>> : std::true_type {};
template <class S> inline constexpr bool is_dual_v = is_dual<std::decay_t<S>>::value;

template <class S> struct is_var : std::false_type {};
template <class T> struct is_var<Var<T>> : std::true_type {};
template <class S> inline constexpr bool is_var_v = is_var<std::decay_t<S>>::value;

// True for every scalar type that carries derivatives.
template <class S> inline constexpr bool is_ad_v = is_dual_v<S> || is_var_v<S>;

// Plain floating-point scalars (float, double, long double).
template <class S> inline constexpr bool is_plain_v = std::is_floating_point_v<std::decay_t<S>>;

// Every scalar the generic path accepts: plain floating point or AD.
template <class S> inline constexpr bool is_scalar_v = is_plain_v<S> || is_ad_v<S>;

// The floating-point type under a scalar: float for Dual<float, N> and Var<float>.
template <class S, class = void> struct scalar_type { using type = std::decay_t<S>; };
template <class T, int N> struct scalar_type<Dual<T, N>> { using type = T; };
template <class T> struct scalar_type<Var<T>> { using type = T; };
template <class S> using scalar_t = typename scalar_type<std::decay_t<S>>::type;

// Number of forward-mode tangent lanes (0 for types without them).
template <class S> struct dual_lanes : std::integral_constant<int, 0> {};
template <class T, int N> struct dual_lanes<Dual<T, N>> : std::integral_constant<int, N> {};
template <class S> inline constexpr int dual_lanes_v = dual_lanes<std::decay_t<S>>::value;

namespace detail {
// The type of an expression mixing A and B: the AD type if one is AD, else
// the common arithmetic type. Two different AD types never mix.
template <class A, class B, class = void> struct promote {};
template <class A, class B>
struct promote<A, B, std::enable_if_t<std::is_arithmetic_v<A> && std::is_arithmetic_v<B>>> {
  using type = std::common_type_t<A, B>;
};
template <class A, class B>
struct promote<A, B, std::enable_if_t<is_ad_v<A> && std::is_arithmetic_v<B>>> { using type = A; };
template <class A, class B>
struct promote<A, B, std::enable_if_t<std::is_arithmetic_v<A> && is_ad_v<B>>> { using type = B; };
template <class A> struct promote<A, A, std::enable_if_t<is_ad_v<A>>> { using type = A; };
}  // namespace detail

template <class A, class B> using promote_t = typename detail::promote<std::decay_t<A>, std::decay_t<B>>::type;

// True when (A, B) may meet in one expression and at least one side is AD.
template <class A, class B, class = void> struct is_ad_pair : std::false_type {};
template <class A, class B>
struct is_ad_pair<A, B, std::void_t<promote_t<A, B>>>
    : std::bool_constant<is_ad_v<A> || is_ad_v<B>> {};
template <class A, class B>
using enable_if_ad_pair_t = std::enable_if_t<is_ad_pair<std::decay_t<A>, std::decay_t<B>>::value, int>;

// True when (A, B) may meet in one expression (plain or AD).
template <class A, class B, class = void> struct is_scalar_pair : std::false_type {};
template <class A, class B>
struct is_scalar_pair<A, B, std::void_t<promote_t<A, B>>> : std::true_type {};
template <class A, class B>
using enable_if_scalar_pair_t = std::enable_if_t<is_scalar_pair<std::decay_t<A>, std::decay_t<B>>::value, int>;

// value_of(x): the primal value, with no derivative information.
template <class T, std::enable_if_t<std::is_arithmetic_v<T>, int> = 0>
DT_HOST_DEVICE constexpr T value_of(T x) { return x; }

// detach(x): the same value as the same scalar type, cut from derivatives.
template <class T, std::enable_if_t<std::is_arithmetic_v<T>, int> = 0>
DT_HOST_DEVICE constexpr T detach(T x) { return x; }

}  // namespace difftrans::ad
