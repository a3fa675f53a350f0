// Distant environment: constant colour or equirectangular RGB map (bilinear,
// differentiable in texels and direction). The one home of the uv convention.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/core/constants.hpp"
#include "difftrans/ad/param_source.hpp"

namespace difftrans::scene {

// Convention (docs/conventions.md), +Y up: direction d = (x, y, z) maps to
//   u = 0.5 + atan2(x, -z) / (2 pi)   in [0, 1], to the right,
//   v = acos(y) / pi                  in [0, 1], down (v = 0 is +Y).
// So -Z is the map's centre (0.5, 0.5), +X is u = 0.75, -X u = 0.25 and +Z
// the seam u = 0 = 1. v is evaluated as atan2(sqrt(x² + z²), y) / pi, which
// equals acos(y) / pi for unit d, is accurate at the poles and makes the
// lookup depend on the direction of d only (d need not be unit).
//
// Texels: width x height, row 0 at the top (v = 0), RGB float, flat:
// index = (row * width + col) * 3 + channel. Texel (col, row) is centred at
// u = (col + 0.5) / width, v = (row + 0.5) / height. Bilinear interpolation
// wraps around in u (the seam is as smooth as anywhere else) and clamps in v:
// within half a texel of a pole the lookup interpolates along the first (or
// last) row only, and its derivative with respect to v is zero there.
//
// Derivatives: atan2 is taken with derivative (x dy - y dx) / max(x² + y², eps)
// and the radius with safe_sqrt, so the derivative with respect to the
// direction is finite everywhere, zero exactly at the poles and exact (the
// true 1/r growth) elsewhere.

enum class EnvironmentKind : int { constant, equirect };

struct EnvMap {
  EnvironmentKind kind = EnvironmentKind::constant;
  ad::ParamSource texels;  // constant: 3 values (RGB); equirect: width * height * 3
  int width = 0, height = 0;
};

// Builders (host): the caller owns the arrays. buffer >= 0 makes the texels
// parameter buffer `buffer` of the pass's ParamSet (see ParamSource).
inline EnvMap constant_environment(const float* rgb, int buffer = -1) {
  EnvMap e;
  e.kind = EnvironmentKind::constant;
  e.texels = ad::ParamSource{rgb, 3, buffer};
  return e;
}
inline EnvMap equirect_environment(const float* texels, int width, int height, int buffer = -1) {
  EnvMap e;
  e.kind = EnvironmentKind::equirect;
  e.texels = ad::ParamSource{texels, std::int32_t(width) * height * 3, buffer};
  e.width = width;
  e.height = height;
  return e;
}

DT_HOST_DEVICE constexpr std::int32_t texel_index(int width, int row, int col, int channel) {
  return (std::int32_t(row) * width + col) * 3 + channel;
}

namespace detail {

// atan2 whose derivative stays finite as (x, y) -> 0: the denominator of the
// rule is clamped at safe_sqrt_eps (the value is the ordinary atan2).
template <class S>
DT_HOST_DEVICE S safe_atan2(const S& y, const S& x) {
  if constexpr (!ad::is_ad_v<S>) {
    return atan2(y, x);
  } else {
    using T = ad::scalar_t<S>;
    const T yv = ad::value_of(y), xv = ad::value_of(x), r2 = xv * xv + yv * yv;
    const T inv = T(1) / (r2 > ad::safe_sqrt_eps<T> ? r2 : ad::safe_sqrt_eps<T>);
    // d atan2(y, x) = (x dy - y dx) / max(x² + y², eps)
    return ad::detail::binary(y, x, T(atan2(yv, xv)), xv * inv, -yv * inv);
  }
}

}  // namespace detail

// (u, v) of a direction, generic over S (see the convention above).
template <class S>
DT_HOST_DEVICE Vec2<S> direction_to_uv(const Vec3<S>& d) {
  using T = ad::scalar_t<S>;
  const T inv_two_pi = inv_two_pi_v<T>, inv_pi = inv_pi_v<T>;  // copies: usable in device code
  const S r = safe_sqrt(d.x * d.x + d.z * d.z);
  const S u = T(0.5) + detail::safe_atan2(d.x, -d.z) * inv_two_pi;
  const S v = detail::safe_atan2(r, d.y) * inv_pi;
  return Vec2<S>(u, v);
}

// The unit direction of (u, v): the inverse of direction_to_uv.
template <class T>
DT_HOST_DEVICE Vec3<T> uv_to_direction(T u, T v) {
  const T phi = two_pi_v<T> * (u - T(0.5)), theta = pi_v<T> * v;
  const T s = sin(theta);
  return Vec3<T>(s * sin(phi), cos(theta), -s * cos(phi));
}

// The four texels (items: index / 3 of their R entry) a bilinear lookup at
// (u, v) blends, and their weights in S. The one place the interpolation is
// defined: lookup_uv uses it, and so does the least-squares fit of a map.
template <class S>
struct Footprint {
  std::int32_t texel[4];
  S weight[4];
  bool valid;  // false for an empty map or non-finite (u, v)
};

template <class S>
DT_HOST_DEVICE Footprint<S> bilinear_footprint(int w, int h, const Vec2<S>& uv) {
  using T = ad::scalar_t<S>;
  Footprint<S> f;
  f.valid = w >= 1 && h >= 1 && isfinite(ad::value_of(uv.x)) && isfinite(ad::value_of(uv.y));
  if (!f.valid) {
    for (int k = 0; k < 4; ++k) {
      f.texel[k] = 0;
      f.weight[k] = S(0);
    }
    return f;
  }
  // columns: wrap around the seam
  const S fu = uv.x * T(w) - T(0.5);
  const T fu_floor = floor(ad::value_of(fu));
  const S tu = fu - fu_floor;  // in [0, 1)
  // fu_floor mod w, in floating point so any finite u is safe
  const T wrapped = fu_floor - T(w) * floor(fu_floor / T(w));
  int c0 = int(wrapped);
  c0 = c0 < 0 ? 0 : (c0 >= w ? w - 1 : c0);
  const int c1 = c0 + 1 == w ? 0 : c0 + 1;
  // rows: clamp at the poles
  const S fv = clamp(uv.y * T(h) - T(0.5), S(0), S(T(h - 1)));
  int r0 = int(floor(ad::value_of(fv)));
  if (r0 > h - 2) r0 = h - 2 < 0 ? 0 : h - 2;
  const int r1 = r0 + 1 < h ? r0 + 1 : r0;
  const S tv = fv - T(r0);  // in [0, 1] (0 when h == 1)
  f.texel[0] = r0 * w + c0;
  f.texel[1] = r0 * w + c1;
  f.texel[2] = r1 * w + c0;
  f.texel[3] = r1 * w + c1;
  f.weight[0] = (T(1) - tu) * (T(1) - tv);
  f.weight[1] = tu * (T(1) - tv);
  f.weight[2] = (T(1) - tu) * tv;
  f.weight[3] = tu * tv;
  return f;
}

// Bilinear lookup at (u, v) of an equirectangular map, generic over S.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> lookup_uv(Reader& reader, const EnvMap& env, const Vec2<S>& uv) {
  if (env.kind == EnvironmentKind::constant) return ad::load3<S>(reader, env.texels, 0);
  const Footprint<S> f = bilinear_footprint(env.width, env.height, uv);
  if (!f.valid) return Vec3<S>(S(0), S(0), S(0));
  Vec3<S> t[4];
  for (int k = 0; k < 4; ++k) t[k] = ad::load3<S>(reader, env.texels, f.texel[k]);
  Vec3<S> c;
  for (int k = 0; k < 3; ++k) c[k] = t[0][k] * f.weight[0] + t[1][k] * f.weight[1] + t[2][k] * f.weight[2] + t[3][k] * f.weight[3];
  return c;
}

// Radiance arriving from direction d (pointing away from the scene), generic
// over S: differentiable with respect to d and, through the reader, the texels.
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> lookup(Reader& reader, const EnvMap& env, const Vec3<S>& d) {
  if (env.kind == EnvironmentKind::constant) return ad::load3<S>(reader, env.texels, 0);
  return lookup_uv(reader, env, direction_to_uv(d));
}

// A smooth, varied w × h equirectangular environment (RGB texels): every
// direction sees another colour, so gradients with respect to the look-up
// direction are not zero.
inline std::vector<float> varied_sky(int w, int h) {
  std::vector<float> t;
  t.reserve(std::size_t(w) * std::size_t(h) * 3);
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const float u = (float(col) + 0.5f) / float(w), v = (float(row) + 0.5f) / float(h);
      t.insert(t.end(), {0.6f + 0.4f * std::sin(6.2831853f * u), 0.5f + 0.4f * std::cos(3.14159f * v), 0.3f + 0.6f * u * v});
    }
  return t;
}

}  // namespace difftrans::scene
