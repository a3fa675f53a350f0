// Ray footprints for the image pass: each sample stands for its stratum of
// the pixel (1 / n of a pixel on a side), and a ray that escapes reads the
// environment averaged over the image of that stratum in the map, instead of
// the map at one point. The image is found as ray differentials: the camera
// ray is traced in Dual<T, 2> whose two lanes are the derivatives with
// respect to the sample's position across the stratum, so every refraction
// and reflection of the tree (the tracer's own generic code, shading normals
// included) carries the footprint along, and an escaping branch's direction
// gives the footprint's two edges in texels. The footprint is cut into
// pieces (at most FootprintSettings::max_pieces along each edge), and the
// map over each piece is averaged in constant time from a summed-area table
// (scene/envmap_box.hpp).
//
// Why: on a map with a small, very bright sun, a glint that covers a few
// hundredths of a pixel is found by a few of the pixel's samples, at full
// brightness, or by none of them, and the pixel's tone-mapped value jumps
// between black and white; converging that takes hundreds of samples per
// pixel. With footprints every sample whose stratum sees part of the sun
// brings its share. What it costs: a trace in Dual<T, 2> instead of T, and
// a bias where the map of the stratum is far from linear (across a
// silhouette or the edge of total internal reflection the derivative says
// nothing about the other side); it vanishes as the strata shrink, since
// the footprints shrink with them, and each box is never narrower than one
// texel, where the box average is the point lookup's bilinear value.
//
// Only the distant map is filtered; a constant environment has nothing to
// filter and a near field (a radiance field, a room) is read at the point.
// An image pass only: gradients keep the point lookup.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "difftrans/ad/dual.hpp"
#include "difftrans/ad/glm.hpp"
#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/pass_options.hpp"
#include "difftrans/render/passes.hpp"
#include "difftrans/render/tracer.hpp"
#include "difftrans/scene/camera.hpp"
#include "difftrans/scene/envmap.hpp"
#include "difftrans/scene/envmap_box.hpp"

namespace difftrans::render {

struct FootprintSettings {
  float scale = 1.0f;         // the footprint's side in strata (1: the sample's own stratum)
  int max_pieces = 4;         // the footprint is cut into at most this many pieces along each edge
  // An edge spanning more than this angle (radians, in longitude or latitude)
  // is shortened to it: far from linear there (grazing the silhouette, the
  // differentials reach across the map while the stratum's rays do not).
  float max_angle = 0.3f;
};

namespace detail {

template <class S>
struct IsPixelDual : std::false_type {};
template <class T>
struct IsPixelDual<ad::Dual<T, 2>> : std::true_type {};

}  // namespace detail

// The map's mean over a footprint centred at texel coordinates `centre`
// with edges `a` and `b` (texels): the parallelogram is cut into pieces no
// wider than a texel along each edge, up to max_pieces per edge, and each
// piece is read as the box around it (a piece within a texel: the bilinear
// value at its centre; see scene/envmap_box.hpp). The box around a tilted
// piece is larger than the piece, so what light leaks past the footprint's
// edge is at most half a piece wide: nothing for footprints up to
// max_pieces texels long, an eighth of the footprint for longer ones.
DT_HOST_DEVICE inline Vec3f footprint_average(const scene::EnvBoxTable& table, Vec2f centre, Vec2f a, Vec2f b,
                                              const FootprintSettings& settings) {
  const float limit_x = settings.max_angle * inv_two_pi_v<float> * float(table.width);
  const float limit_y = settings.max_angle * inv_pi_v<float> * float(table.height);
  const auto shorten = [&](Vec2f e) {  // an edge whose linearization means nothing any more
    const float sx = fabsf(e.x) > limit_x ? limit_x / fabsf(e.x) : 1.0f;
    const float sy = fabsf(e.y) > limit_y ? limit_y / fabsf(e.y) : 1.0f;
    return e * (sx < sy ? sx : sy);
  };
  a = shorten(a);
  b = shorten(b);
  const auto pieces_along = [&](Vec2f e) {  // pieces at most a texel long in x and in y
    const int k = int(ceilf(fabsf(e.x) > fabsf(e.y) ? fabsf(e.x) : fabsf(e.y)));
    return k < 1 ? 1 : (k > settings.max_pieces ? settings.max_pieces : k);
  };
  const int ka = pieces_along(a), kb = pieces_along(b);
  const Vec2f step_a = a / float(ka), step_b = b / float(kb);
  const float hx = 0.5f * (fabsf(step_a.x) + fabsf(step_b.x)), hy = 0.5f * (fabsf(step_a.y) + fabsf(step_b.y));
  const Vec2f first = centre - 0.5f * (a - step_a) - 0.5f * (b - step_b);
  Vec3f sum(0.0f);
  for (int j = 0; j < kb; ++j)
    for (int i = 0; i < ka; ++i) {
      const Vec2f c = first + float(i) * step_a + float(j) * step_b;
      sum += scene::env_box_average(table, c.x, c.y, hx, hy);
    }
  return sum / float(ka * kb);
}

// The escape of the footprint pass: a branch traced in Dual<T, 2> over the
// sample's position reads the map averaged over its footprint (values only:
// the lanes are ray differentials, not derivatives of the image); any other
// scalar, or a map that is not equirectangular, reads the point.
struct FootprintEscape {
  scene::EnvBoxTable table;
  FootprintSettings settings;

  template <class S, class Reader>
  DT_HOST_DEVICE Vec3<S> operator()(Reader& reader, const SceneView& scene, const Vec3<S>& o, const Vec3<S>& d) const {
    if constexpr (detail::IsPixelDual<S>::value) {
      if (scene.environment.kind == scene::EnvironmentKind::equirect && table.sums != nullptr) {
        const Vec2<S> uv = scene::direction_to_uv(d);
        const float w = float(table.width), h = float(table.height), k = settings.scale;
        const Vec2f centre(float(uv.x.value) * w, float(uv.y.value) * h);
        const Vec2f a(float(uv.x.grad[0]) * w * k, float(uv.y.grad[0]) * h * k);
        const Vec2f b(float(uv.x.grad[1]) * w * k, float(uv.y.grad[1]) * h * k);
        if (isfinite(a.x) && isfinite(a.y) && isfinite(b.x) && isfinite(b.y)) {
          const Vec3f L = footprint_average(table, centre, a, b, settings);
          return Vec3<S>(S(L.x), S(L.y), S(L.z));
        }
      }
    }
    return DistantEscape{}(reader, scene, o, d);
  }
};

// The camera ray through continuous pixel coordinates (px, py), its
// direction carrying its derivatives along x and y times `cell` (the
// stratum's side in pixels) in the two lanes of Dual<T, 2>. The value is
// Camera::ray_through's, to the bit.
template <class T>
DT_HOST_DEVICE Vec3<ad::Dual<T, 2>> ray_differential(const scene::Camera& cam, float px, float py, float cell) {
  const scene::Ray r = cam.ray_through(px, py);
  const Vec3f dc((px - cam.cx) / cam.fx, -(py - cam.cy) / cam.fy, -1.0f);
  const Vec3f w = Vec3f(cam.camera_to_world * Vec4<float>(dc, 0.0f));
  const float len = sqrtf(glm::dot(w, w));
  const Vec3f wx = Vec3f(cam.camera_to_world * Vec4<float>(cell / cam.fx, 0.0f, 0.0f, 0.0f));
  const Vec3f wy = Vec3f(cam.camera_to_world * Vec4<float>(0.0f, -cell / cam.fy, 0.0f, 0.0f));
  // d(w / |w|) = (dw − d (d · dw)) / |w|
  const Vec3f dx = (wx - r.direction * glm::dot(r.direction, wx)) / len;
  const Vec3f dy = (wy - r.direction * glm::dot(r.direction, wy)) / len;
  Vec3<ad::Dual<T, 2>> d;
  for (int c = 0; c < 3; ++c) {
    d[c] = ad::Dual<T, 2>(r.direction[c]);
    d[c].grad[0] = T(dx[c]);
    d[c].grad[1] = T(dy[c]);
  }
  return d;
}

// Radiance along the camera ray through (px, py) traced in Dual<T, 2> with
// the ray differentials of a stratum `cell` pixels wide; escaping branches
// read `escape` (FootprintEscape: the map over their footprints). Reader:
// a ParamReader<Dual<T, 2>> of the pass.
template <class T, class Accel, class Reader, class Escape = FootprintEscape>
DT_HOST_DEVICE Vec3<T> trace_footprint(const SceneView& scene, const Accel& accel, Reader& reader,
                                       const scene::Camera& cam, float px, float py, float cell,
                                       const TraceSettings& settings, const Escape& escape,
                                       TraceStats* stats = nullptr) {
  using D = ad::Dual<T, 2>;
  const scene::Ray r = cam.ray_through(px, py);
  const Vec3<D> direction = ray_differential<T>(cam, px, py, cell);
  const Vec3<D> radiance = detail::trace_camera_ray<D>(scene, accel, reader, r.origin, r.direction, settings, stats,
                                                       escape, detail::SumBranches{}, &direction);
  return Vec3<T>(radiance.x.value, radiance.y.value, radiance.z.value);
}

// The image (width·height·3 linear RGB, like render_image) with every sample
// reading the environment over its stratum's footprint. Scenes without an
// equirectangular map, or with a near field, are rendered by render_image.
template <class T = float>
std::vector<T> render_image_footprints(const HostScene& s, const scene::Camera& cam, const PassOptions& opt = {},
                                       const FootprintSettings& settings = {}, PassStats* stats = nullptr) {
  if (s.near_field || s.environment_width <= 0) return render_image<T>(s, cam, opt, stats);
  const std::vector<double> sums = scene::env_box_sums(s.environment.data(), s.environment_width, s.environment_height);
  const FootprintEscape escape{scene::EnvBoxTable{sums.data(), s.environment_width, s.environment_height}, settings};
  const int n = opt.samples_per_axis;
  const float cell = 1.0f / float(n);
  std::vector<T> image(std::size_t(cam.width) * cam.height * 3, T(0));
  const SceneView view = s.view(false);
  detail::sample_pass<ad::Dual<T, 2>>(
      s.params(), cam, n, stats,
      [&](ad::ParamReader<ad::Dual<T, 2>>& reader, std::int64_t pix, int k, TraceStats& ts) {
        const Vec2f p = pixel_sample_point(cam, n, pix, k);
        return trace_footprint<T>(view, s.accel(), reader, cam, p.x, p.y, cell, opt.trace, escape, &ts);
      },
      [&](std::size_t i, const Vec3<T>& L, float wt) {
        for (int c = 0; c < 3; ++c) image[i + std::size_t(c)] += T(wt) * L[c];
      });
  return image;
}

}  // namespace difftrans::render
