// The glue that lets GLM vectors hold AD scalars: std::numeric_limits for
// Dual and Var (GLM's geometric functions require is_iec559), plus value_of /
// detach / all_finite lifted to vectors.
#pragma once

#include <limits>

#include "difftrans/ad/math.hpp"
#include "difftrans/core/vec.hpp"

namespace difftrans::ad::detail {
// numeric_limits of an AD scalar: those of T, lifted to constants.
template <class S, class T>
struct ad_numeric_limits : std::numeric_limits<T> {
  static constexpr bool is_specialized = true;
  static constexpr bool is_iec559 = std::numeric_limits<T>::is_iec559;
  static constexpr S min() noexcept { return S(std::numeric_limits<T>::min()); }
  static constexpr S max() noexcept { return S(std::numeric_limits<T>::max()); }
  static constexpr S lowest() noexcept { return S(std::numeric_limits<T>::lowest()); }
  static constexpr S epsilon() noexcept { return S(std::numeric_limits<T>::epsilon()); }
  static constexpr S round_error() noexcept { return S(std::numeric_limits<T>::round_error()); }
  static constexpr S infinity() noexcept { return S(std::numeric_limits<T>::infinity()); }
  static constexpr S quiet_NaN() noexcept { return S(std::numeric_limits<T>::quiet_NaN()); }
  static constexpr S signaling_NaN() noexcept { return S(std::numeric_limits<T>::signaling_NaN()); }
  static constexpr S denorm_min() noexcept { return S(std::numeric_limits<T>::denorm_min()); }
};
}  // namespace difftrans::ad::detail

namespace std {
template <class T, int N>
class numeric_limits<difftrans::ad::Dual<T, N>>
    : public difftrans::ad::detail::ad_numeric_limits<difftrans::ad::Dual<T, N>, T> {};
template <class T>
class numeric_limits<difftrans::ad::Var<T>>
    : public difftrans::ad::detail::ad_numeric_limits<difftrans::ad::Var<T>, T> {};
}  // namespace std

namespace difftrans::ad {

template <glm::length_t L, class S, glm::qualifier Q>
DT_HOST_DEVICE glm::vec<L, scalar_t<S>, Q> value_of(const glm::vec<L, S, Q>& v) {
  glm::vec<L, scalar_t<S>, Q> r;
  for (glm::length_t i = 0; i < L; ++i) r[i] = value_of(v[i]);
  return r;
}

template <glm::length_t L, class S, glm::qualifier Q>
DT_HOST_DEVICE glm::vec<L, S, Q> detach(const glm::vec<L, S, Q>& v) {
  glm::vec<L, S, Q> r;
  for (glm::length_t i = 0; i < L; ++i) r[i] = detach(v[i]);
  return r;
}

template <glm::length_t L, class S, glm::qualifier Q>
DT_HOST_DEVICE bool all_finite(const glm::vec<L, S, Q>& v) {
  bool ok = true;
  for (glm::length_t i = 0; i < L; ++i) ok = ok && all_finite(v[i]);
  return ok;
}

// Converts a plain vector to scalar S (constants for AD types).
template <class S, glm::length_t L, class T, glm::qualifier Q>
DT_HOST_DEVICE glm::vec<L, S, Q> lift(const glm::vec<L, T, Q>& v) {
  glm::vec<L, S, Q> r;
  for (glm::length_t i = 0; i < L; ++i) r[i] = S(v[i]);
  return r;
}

}  // namespace difftrans::ad

namespace difftrans {
// Brings the vector overloads above into namespace difftrans as well (the
// scalar ones were brought in by math.hpp).
using ad::all_finite;
using ad::detach;
using ad::lift;
using ad::value_of;
}  // namespace difftrans
