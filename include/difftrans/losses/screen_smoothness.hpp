// The screen-space smoothness term of stage 1 (DiffTrans, after the depth and
// normal smoothness of screen-space regularizers): per view, the depth and
// normal maps of the rasterized mesh, and
//   L = mean over valid pixels of |∇d| + |∇n| + |∇²n|
// (finite differences between adjacent covered pixels, the 5-point Laplacian
// of the normal), with its gradient to the vertex positions through the
// covering triangles (the raster, i.e. visibility, held fixed).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "difftrans/ad/block_gradients.hpp"
#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/params.hpp"
#include "difftrans/core/parallel.hpp"
#include "difftrans/scene/camera.hpp"
#include "difftrans/scene/mesh.hpp"
#include "difftrans/render/raster.hpp"

namespace difftrans::losses {

// What the smoothness term sees at one pixel, re-evaluated in S on the
// covering triangle along the ray through the pixel centre.
template <class S>
struct PixelGeometry {
  S depth;       // view depth of the hit point
  Vec3<S> n;     // unit world-space normal (shading or face normal)
  bool valid;
};

template <class S, class Reader>
DT_HOST_DEVICE PixelGeometry<S> pixel_geometry(Reader& reader, const scene::MeshView& m, const scene::Camera& cam,
                                               std::int32_t tri, int x, int y, bool face_normals,
                                               scene::NormalMode mode = scene::NormalMode::automatic) {
  const scene::Ray ray = cam.generate_ray(x, y);
  const scene::SurfaceHit<S> h =
      scene::reevaluate_hit<S>(reader, m, tri, ad::lift<S>(ray.origin), ad::lift<S>(ray.direction), mode);
  PixelGeometry<S> g;
  g.valid = h.hit.valid && h.point.valid;
  g.depth = -cam.to_camera(h.point.p).z;
  g.n = face_normals ? h.point.ng : h.point.n;
  return g;
}

// Per-pixel maps of a raster: depth (0 on background) and unit normals (3 per pixel, 0 on background).
struct GeometryMaps {
  int width = 0, height = 0;
  std::vector<float> depth, normal;
  std::vector<unsigned char> valid;
};

struct SmoothnessOptions {
  float depth_weight = 1.0f;      // |∇d|
  float normal_weight = 1.0f;     // |∇n| (L1 over the components)
  float laplacian_weight = 1.0f;  // |∇²n| (5-point Laplacian, L1 over the components)
  bool face_normals = false;      // geometric normal of the triangle instead of the interpolated one
};

inline GeometryMaps geometry_maps(const scene::TriangleMesh& m, const scene::Camera& cam, const render::Raster& r,
                                  const SmoothnessOptions& opt = {}) {
  GeometryMaps g;
  g.width = r.width;
  g.height = r.height;
  const std::size_t n = std::size_t(r.pixels());
  g.depth.assign(n, 0.0f);
  g.normal.assign(3 * n, 0.0f);
  g.valid.assign(n, 0);
  const scene::MeshView view = m.view();
  parallel_for(r.pixels(), 1024, [&](std::int64_t b, std::int64_t e, int) {
    ad::ParamReader<float> reader(nullptr);
    for (std::int64_t p = b; p < e; ++p) {
      const std::int32_t t = r.triangle[std::size_t(p)];
      if (t < 0) continue;
      const PixelGeometry<float> pg =
          pixel_geometry<float>(reader, view, cam, t, int(p % r.width), int(p / r.width), opt.face_normals);
      if (!pg.valid) continue;
      g.valid[std::size_t(p)] = 1;
      g.depth[std::size_t(p)] = pg.depth;
      for (int c = 0; c < 3; ++c) g.normal[3 * std::size_t(p) + c] = pg.n[c];
    }
  });
  return g;
}

// The smoothness loss over the maps, normalized by the number of valid
// pixels: finite differences between horizontally / vertically adjacent valid
// pixels (depth and normal), and the 5-point Laplacian of the normal where a
// pixel and its four neighbours are valid. When the adjoint arrays are given
// (size of depth / normal), writes dLoss/ddepth and dLoss/dnormal there
// (subgradient, sign(0) = 0).
inline double smoothness_loss(const GeometryMaps& g, const SmoothnessOptions& opt = {},
                              float* depth_adjoint = nullptr, float* normal_adjoint = nullptr) {
  const int W = g.width, H = g.height;
  std::int64_t count = 0;
  for (unsigned char v : g.valid) count += v;
  if (count == 0) return 0.0;
  const double inv = 1.0 / double(count);
  const auto sgn = [](float v) { return v > 0.0f ? 1.0f : (v < 0.0f ? -1.0f : 0.0f); };
  const auto at = [&](int x, int y) { return std::size_t(y) * std::size_t(W) + std::size_t(x); };
  if (depth_adjoint) std::fill(depth_adjoint, depth_adjoint + g.depth.size(), 0.0f);
  if (normal_adjoint) std::fill(normal_adjoint, normal_adjoint + g.normal.size(), 0.0f);
  double sum = 0.0;
  const float wd = float(opt.depth_weight * inv), wn = float(opt.normal_weight * inv),
              wl = float(opt.laplacian_weight * inv);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const std::size_t p = at(x, y);
      if (!g.valid[p]) continue;
      for (int axis = 0; axis < 2; ++axis) {
        const int xq = axis == 0 ? x + 1 : x, yq = axis == 0 ? y : y + 1;
        if (xq >= W || yq >= H || !g.valid[at(xq, yq)]) continue;
        const std::size_t q = at(xq, yq);
        const float dd = g.depth[q] - g.depth[p];
        sum += double(opt.depth_weight) * std::fabs(dd) * inv;
        if (depth_adjoint) {
          depth_adjoint[q] += wd * sgn(dd);
          depth_adjoint[p] -= wd * sgn(dd);
        }
        for (int c = 0; c < 3; ++c) {
          const float dn = g.normal[3 * q + c] - g.normal[3 * p + c];
          sum += double(opt.normal_weight) * std::fabs(dn) * inv;
          if (normal_adjoint) {
            normal_adjoint[3 * q + c] += wn * sgn(dn);
            normal_adjoint[3 * p + c] -= wn * sgn(dn);
          }
        }
      }
      if (x == 0 || y == 0 || x + 1 >= W || y + 1 >= H) continue;
      const std::size_t nbr[4] = {at(x - 1, y), at(x + 1, y), at(x, y - 1), at(x, y + 1)};
      bool all = true;
      for (std::size_t q : nbr) all = all && g.valid[q];
      if (!all || opt.laplacian_weight == 0.0f) continue;
      for (int c = 0; c < 3; ++c) {
        float lap = -4.0f * g.normal[3 * p + c];
        for (std::size_t q : nbr) lap += g.normal[3 * q + c];
        sum += double(opt.laplacian_weight) * std::fabs(lap) * inv;
        if (normal_adjoint) {
          const float s = wl * sgn(lap);
          normal_adjoint[3 * p + c] -= 4.0f * s;
          for (std::size_t q : nbr) normal_adjoint[3 * q + c] += s;
        }
      }
    }
  return sum;
}

// Reverse mode through the maps: given dLoss/ddepth (1 per pixel) and
// dLoss/dnormal (3 per pixel) of the maps of raster r, adds dLoss/dposition
// into grad_positions. Depth and normal are re-evaluated in Var on the
// covering triangle along the pixel's centre ray (Möller–Trumbore); the vertex
// normals are leaves of their own, folded back into the positions once at the
// end (TriangleMesh::normals_backward, through the one-rings). The mesh's
// vertex normals must be current (update_normals). Pixels with a zero adjoint
// cost nothing. The raster (which triangle covers which pixel) is
// held fixed: no silhouette term here.
inline void geometry_backward(const scene::TriangleMesh& m, const scene::Camera& cam, const render::Raster& r,
                              const float* depth_adjoint, const float* normal_adjoint, float* grad_positions,
                              const SmoothnessOptions& opt = {}) {
  using V = ad::Var<float>;
  ad::ParamSet set;
  set.buffers[0].values = m.positions.data();
  set.buffers[0].size = std::int32_t(m.positions.size());
  set.buffers[0].gradient = grad_positions;
  std::vector<float> grad_normals(m.vertex_normals.size(), 0.0f);
  set.buffers[1].values = m.vertex_normals.data();
  set.buffers[1].size = std::int32_t(m.vertex_normals.size());
  set.buffers[1].gradient = grad_normals.data();
  const scene::MeshView view = m.view(0, 1);
  ad::BlockGradients blocks(set, r.pixels(), 32, 256);  // a fixed order of sums
  parallel_for(blocks.count(), 1, [&](std::int64_t kb, std::int64_t ke, int) {
    ad::Tape<float> tape(1 << 10);
    std::vector<ad::LeafRecord> log(64);
    for (std::int64_t k = kb; k < ke; ++k) {
      ad::ParamReader<V> reader(&blocks.set(k), &tape, log.data(), std::int32_t(log.size()));
      for (std::int64_t p = blocks.begin(k); p < blocks.end(k); ++p) {
        const std::int32_t t = r.triangle[std::size_t(p)];
        if (t < 0) continue;
        const float ad_d = depth_adjoint ? depth_adjoint[p] : 0.0f;
        const float zero[3] = {0.0f, 0.0f, 0.0f};
        const float* ad_n = normal_adjoint ? normal_adjoint + 3 * p : zero;
        if (ad_d == 0.0f && ad_n[0] == 0.0f && ad_n[1] == 0.0f && ad_n[2] == 0.0f) continue;
        tape.reset();
        reader.clear();
        const PixelGeometry<V> pg = pixel_geometry<V>(reader, view, cam, t, int(p % r.width), int(p / r.width),
                                                      opt.face_normals, scene::NormalMode::parameter);
        if (tape.overflowed() || reader.overflowed() || !pg.valid) {
          reader.clear();
          continue;
        }
        tape.zero_adjoints();
        tape.seed(pg.depth, ad_d);
        for (int c = 0; c < 3; ++c) tape.seed(pg.n[c], ad_n[c]);
        tape.propagate();
        reader.scatter();
      }
    }
  });
  blocks.reduce();
  m.normals_backward(grad_normals.data(), grad_positions);
}

// The smoothness loss of a mesh in a camera and, when grad_positions is given,
// its gradient w.r.t. the vertex positions added there (geometry_backward of
// the loss's adjoints). The maps are returned through maps_out when given.
inline double smoothness_gradient(const scene::TriangleMesh& m, const scene::Camera& cam, float* grad_positions,
                                  const SmoothnessOptions& opt = {}, const render::RasterOptions& ropt = {},
                                  GeometryMaps* maps_out = nullptr) {
  const render::Raster r = render::rasterize(m, cam, ropt);
  GeometryMaps g = geometry_maps(m, cam, r, opt);
  std::vector<float> ad_depth(g.depth.size()), ad_normal(g.normal.size());
  const double loss = smoothness_loss(g, opt, ad_depth.data(), ad_normal.data());
  if (grad_positions) geometry_backward(m, cam, r, ad_depth.data(), ad_normal.data(), grad_positions, opt);
  if (maps_out) *maps_out = std::move(g);
  return loss;
}

}  // namespace difftrans::losses
