// Differentiable silhouettes: the anti-aliased coverage mask of a rasterized
// mesh (nvdiffrast-style analytic anti-aliasing of the silhouette edges, Laine
// et al. 2020) with its derivatives to the vertex positions, in reverse
// (silhouette_backward) and forward (silhouette_derivative) mode.
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
#include "difftrans/geometry/topology.hpp"
#include "difftrans/render/raster.hpp"

namespace difftrans::render {

// ------------------------------------------------------------------ anti-aliasing

// One pixel pair straddling the silhouette: `covered` shows a triangle, `other`
// the background; (v0, v1) is the silhouette edge that crosses the segment
// between the two pixel centres. The pair is (x, y)-(x+1, y) for axis 0 and
// (x, y)-(x, y+1) for axis 1; covered_low says the covered pixel is (x, y).
struct SilhouetteCrossing {
  std::int32_t covered, other;
  std::int32_t v0, v1;
  std::int32_t x, y;
  std::int8_t axis;
  bool covered_low;
};

// Coverage moved by one pair: `gain` is added to the background pixel (the
// silhouette reaches past the boundary between the two pixels), `loss` taken
// from the covered one (it stops short of it). At most one is non-zero.
template <class S>
struct PairCoverage {
  S gain, loss;
};

// The per-pair computation, generic over S. e0, e1: the silhouette edge's
// projected end points (continuous pixel coordinates). The edge meets the line
// through the two pixel centres at u_e (u: x for axis 0, y for axis 1); with
// d = u_e - (boundary between the two pixels), clamped to [-1/2, 1/2], the
// front surface reaches d past the boundary: the background pixel gains
// max(s d, 0) and the covered pixel loses max(-s d, 0), s = +1 when the covered
// pixel is the low one. A 1-D coverage estimate, exact for an edge that stays
// within one pixel column (row) over the pixel's height (width).
template <class S>
DT_HOST_DEVICE PairCoverage<S> pair_coverage(const Vec2<S>& e0, const Vec2<S>& e1, int x, int y, int axis,
                                             bool covered_low) {
  using T = ad::scalar_t<S>;
  const int u_axis = axis == 0 ? 0 : 1, v_axis = 1 - u_axis;
  const T v_line = T(axis == 0 ? y : x) + T(0.5);
  const T boundary = T(axis == 0 ? x : y) + T(1);
  PairCoverage<S> r{S(0), S(0)};
  const S dv = e1[v_axis] - e0[v_axis];
  if (!(abs(value_of(dv)) > T(0))) return r;  // parallel to the pair: no crossing (never recorded)
  const S s = (S(v_line) - e0[v_axis]) / dv;
  const S u = e0[u_axis] + s * (e1[u_axis] - e0[u_axis]);
  S d = clamp(u - boundary, S(T(-0.5)), S(T(0.5)));
  if (!covered_low) d = -d;
  if (value_of(d) > T(0)) r.gain = d; else r.loss = -d;
  return r;
}

// The pair's coverage from the silhouette edge's vertices, read through the
// reader (leaves for Var, tangents for Dual, constants for float).
template <class S, class Reader>
DT_HOST_DEVICE PairCoverage<S> crossing_coverage(Reader& reader, const ad::ParamSource& positions,
                                                 const scene::Camera& cam, const SilhouetteCrossing& c) {
  const scene::Projection<S> a = cam.project(ad::load3<S>(reader, positions, c.v0));
  const scene::Projection<S> b = cam.project(ad::load3<S>(reader, positions, c.v1));
  if (!a.valid || !b.valid) return PairCoverage<S>{S(0), S(0)};
  return pair_coverage(a.pixel, b.pixel, c.x, c.y, c.axis, c.covered_low);
}

namespace detail {

// Where the segment from `from` (inside triangle tri) moving along +u (dir > 0)
// or -u leaves the triangle, on the line v = v_line: the edge k it leaves
// through and its u, or -1 when no edge crosses the line.
inline int exit_edge(const Raster& r, const std::int32_t* tri, int u_axis, float v_line, float dir, float* u_exit) {
  const int v_axis = 1 - u_axis;
  int best = -1;
  float best_u = 0.0f;
  for (int k = 0; k < 3; ++k) {
    const Vec2f a = r.screen[std::size_t(tri[k])], b = r.screen[std::size_t(tri[(k + 1) % 3])];
    const float da = a[v_axis] - v_line, db = b[v_axis] - v_line;
    if ((da > 0.0f && db > 0.0f) || (da < 0.0f && db < 0.0f) || a[v_axis] == b[v_axis]) continue;
    const float s = da / (da - db);
    const float u = a[u_axis] + s * (b[u_axis] - a[u_axis]);
    if (best < 0 || dir * (u - best_u) > 0.0f) {
      best = k;
      best_u = u;
    }
  }
  *u_exit = best_u;
  return best;
}

// Whether triangle `next`, across edge (a, b) of `cur`, continues the surface
// in screen space (its third vertex lies strictly on the other side of the
// edge's line than cur's third vertex) rather than folding back over it.
inline bool continues_across(const Raster& r, const std::int32_t* cur, int k, const std::int32_t* next) {
  const std::int32_t ia = cur[k], ib = cur[(k + 1) % 3], ic = cur[(k + 2) % 3];
  std::int32_t in = -1;
  for (int j = 0; j < 3; ++j)
    if (next[j] != ia && next[j] != ib) in = next[j];
  if (in < 0) return false;
  const Vec2f a = r.screen[std::size_t(ia)], b = r.screen[std::size_t(ib)];
  const float sc = cross2(b - a, r.screen[std::size_t(ic)] - a), sn = cross2(b - a, r.screen[std::size_t(in)] - a);
  return (sc > 0.0f && sn < 0.0f) || (sc < 0.0f && sn > 0.0f);
}

}  // namespace detail

struct SilhouetteOptions {
  RasterOptions raster;
  // Steps of the walk from the covered pixel's triangle across edges that do
  // not fold, to the silhouette edge (thin triangles near a silhouette often
  // cover no pixel centre).
  int max_walk = 64;
};

// Finds the silhouette crossings of a raster. Rule: for each pair of
// horizontally or vertically adjacent pixels, exactly one of which is
// covered, walk along the segment between their centres from the covered
// pixel's triangle, crossing edges whose other triangle continues the
// surface in screen space, until an edge is reached that is a silhouette
// edge: a boundary or non-manifold edge, or one whose other triangle folds
// back over it (lies on the same side of it in screen space) or is not drawn.
// That edge's crossing is recorded when it is at least as steep as the pair
// direction asks (|dv| >= |du| for horizontal pairs, > for vertical ones), so
// that each edge is anti-aliased along one direction only. Pairs with two
// covered pixels leave the coverage unchanged (both are 1) and are skipped.
inline std::vector<SilhouetteCrossing> find_crossings(const Raster& r, const std::int32_t* triangles,
                                                      const geometry::TriangleNeighbors& nb, int max_walk = 64) {
  const int W = r.width, H = r.height;
  std::vector<std::vector<SilhouetteCrossing>> rows(std::size_t(std::max(H, 0)));
  parallel_for(H, 4, [&](std::int64_t y0, std::int64_t y1, int) {
    for (std::int64_t yy = y0; yy < y1; ++yy) {
      const int y = int(yy);
      auto& out = rows[std::size_t(y)];
      for (int x = 0; x < W; ++x) {
        for (int axis = 0; axis < 2; ++axis) {
          const int xo = axis == 0 ? x + 1 : x, yo = axis == 0 ? y : y + 1;
          if (xo >= W || yo >= H) continue;
          const std::int64_t pl = std::int64_t(y) * W + x, ph = std::int64_t(yo) * W + xo;
          const bool cl = r.covered(pl), ch = r.covered(ph);
          if (cl == ch) continue;
          const std::int64_t pc = cl ? pl : ph, po = cl ? ph : pl;
          const int u_axis = axis == 0 ? 0 : 1, v_axis = 1 - u_axis;
          const float v_line = float(axis == 0 ? y : x) + 0.5f;
          const float dir = cl ? 1.0f : -1.0f;
          const float u_other = float(axis == 0 ? xo : yo) + 0.5f - (cl ? 0.0f : 1.0f);
          std::int32_t t = r.triangle[std::size_t(pc)];
          for (int step = 0; step <= max_walk; ++step) {
            const std::int32_t* tri = triangles + 3 * t;
            float u_exit;
            const int k = detail::exit_edge(r, tri, u_axis, v_line, dir, &u_exit);
            if (k < 0 || dir * (u_exit - u_other) >= 0.0f) break;  // no exit before the other centre: skip
            const std::int32_t n = nb.across[std::size_t(3 * t + k)];
            const bool silhouette = n < 0 || !detail::drawable(r, triangles + 3 * n) ||
                                    !detail::continues_across(r, tri, k, triangles + 3 * n);
            if (!silhouette) {
              t = n;
              continue;
            }
            const std::int32_t v0 = tri[k], v1 = tri[(k + 1) % 3];
            const Vec2f e = r.screen[std::size_t(v1)] - r.screen[std::size_t(v0)];
            const float du = std::fabs(e[u_axis]), dv = std::fabs(e[v_axis]);
            if (axis == 0 ? dv >= du : dv > du)
              out.push_back(SilhouetteCrossing{std::int32_t(pc), std::int32_t(po), v0, v1, x, y, std::int8_t(axis), cl});
            break;
          }
        }
      }
    }
  });
  std::vector<SilhouetteCrossing> all;
  std::size_t total = 0;
  for (const auto& v : rows) total += v.size();
  all.reserve(total);
  for (const auto& v : rows) all.insert(all.end(), v.begin(), v.end());
  return all;
}

// A rasterized view with its silhouette crossings: the discrete part of every
// silhouette pass, computed once in float.
struct SilhouetteFrame {
  Raster raster;
  std::vector<SilhouetteCrossing> crossings;
};

inline SilhouetteFrame prepare_silhouette(const scene::TriangleMesh& m, const geometry::TriangleNeighbors& nb,
                                          const scene::Camera& cam, const SilhouetteOptions& opt = {}) {
  SilhouetteFrame f;
  f.raster = rasterize(m, cam, opt.raster);
  f.crossings = find_crossings(f.raster, m.triangles.data(), nb, opt.max_walk);
  return f;
}

// The binary coverage (1 where a triangle covers the centre, else 0).
inline std::vector<float> coverage_mask(const Raster& r) {
  std::vector<float> m(std::size_t(r.pixels()), 0.0f);
  for (std::size_t p = 0; p < m.size(); ++p) m[p] = r.triangle[p] >= 0 ? 1.0f : 0.0f;
  return m;
}

// The anti-aliased mask of a prepared frame, crossings evaluated in precision
// T (float; double for references). Values are not clamped: a pixel between
// two close silhouettes may leave [0, 1] slightly.
template <class T = float>
std::vector<T> antialiased_mask(const SilhouetteFrame& f, const scene::TriangleMesh& m, const scene::Camera& cam) {
  std::vector<T> mask(std::size_t(f.raster.pixels()), T(0));
  for (std::size_t p = 0; p < mask.size(); ++p) mask[p] = f.raster.triangle[p] >= 0 ? T(1) : T(0);
  const ad::ParamSource pos{m.positions.data(), std::int32_t(m.positions.size()), -1};
  ad::ParamReader<T> reader(nullptr);
  for (const SilhouetteCrossing& c : f.crossings) {  // cheap: a few per silhouette pixel
    const PairCoverage<T> pc = crossing_coverage<T>(reader, pos, cam, c);
    mask[std::size_t(c.other)] += pc.gain;
    mask[std::size_t(c.covered)] -= pc.loss;
  }
  return mask;
}

// The anti-aliased silhouette mask of a mesh in a camera (width·height values).
template <class T = float>
std::vector<T> silhouette_mask(const scene::TriangleMesh& m, const scene::Camera& cam,
                               const geometry::TriangleNeighbors* nb = nullptr, const SilhouetteOptions& opt = {}) {
  const geometry::TriangleNeighbors own = nb ? geometry::TriangleNeighbors{} : geometry::TriangleNeighbors::build(m);
  const SilhouetteFrame f = prepare_silhouette(m, nb ? *nb : own, cam, opt);
  return antialiased_mask<T>(f, m, cam);
}

struct SilhouetteStats {
  std::int64_t crossings = 0;  // pixel pairs straddling the silhouette that were anti-aliased
  std::int64_t covered = 0;    // pixels covered by a triangle
};

// Reverse mode on a prepared frame: adds dLoss/dposition (3 per vertex) into
// grad_positions given dLoss/dmask per pixel. Only pixel pairs straddling the
// silhouette contribute (the coverage is otherwise piecewise constant); one
// small tape per crossing (two vertices, six leaves), summed in a fixed
// order (ad/block_gradients.hpp): the same bits for any number of threads.
inline void silhouette_backward(const SilhouetteFrame& f, const scene::TriangleMesh& m, const scene::Camera& cam,
                                const float* mask_adjoint, float* grad_positions) {
  using V = ad::Var<float>;
  ad::ParamSet set;
  set.buffers[0].values = m.positions.data();
  set.buffers[0].size = std::int32_t(m.positions.size());
  set.buffers[0].gradient = grad_positions;
  const ad::ParamSource pos{m.positions.data(), std::int32_t(m.positions.size()), 0};
  ad::BlockGradients blocks(set, std::int64_t(f.crossings.size()), 32, 256);  // a fixed order of sums
  parallel_for(blocks.count(), 1, [&](std::int64_t kb, std::int64_t ke, int) {
    ad::Tape<float> tape(256);
    ad::LeafRecord log[8];
    for (std::int64_t k = kb; k < ke; ++k) {
      ad::ParamReader<V> reader(&blocks.set(k), &tape, log, 8);
      for (std::int64_t i = blocks.begin(k); i < blocks.end(k); ++i) {
        const SilhouetteCrossing& c = f.crossings[std::size_t(i)];
        const float ag = mask_adjoint[c.other], al = mask_adjoint[c.covered];
        if (ag == 0.0f && al == 0.0f) continue;
        tape.reset();
        reader.clear();
        const PairCoverage<V> pc = crossing_coverage<V>(reader, pos, cam, c);
        tape.zero_adjoints();
        tape.seed(pc.gain, ag);
        tape.seed(pc.loss, -al);
        tape.propagate();
        reader.scatter();
      }
    }
  });
  blocks.reduce();
}

// The same from scratch (rasterize, find crossings, backward); returns the mask.
inline std::vector<float> silhouette_gradient(const scene::TriangleMesh& m, const scene::Camera& cam,
                                              const float* mask_adjoint, float* grad_positions,
                                              const geometry::TriangleNeighbors* nb = nullptr,
                                              const SilhouetteOptions& opt = {}, SilhouetteStats* stats = nullptr) {
  const geometry::TriangleNeighbors own = nb ? geometry::TriangleNeighbors{} : geometry::TriangleNeighbors::build(m);
  const SilhouetteFrame f = prepare_silhouette(m, nb ? *nb : own, cam, opt);
  std::vector<float> mask = antialiased_mask<float>(f, m, cam);
  silhouette_backward(f, m, cam, mask_adjoint, grad_positions);
  if (stats) {
    stats->crossings = std::int64_t(f.crossings.size());
    stats->covered = 0;
    for (std::int32_t t : f.raster.triangle) stats->covered += t >= 0;
  }
  return mask;
}

// Forward mode: the mask and its derivative along a displacement of the
// vertex positions (`direction`, 3 per vertex), with Dual<float, 1>.
struct MaskDerivative {
  std::vector<float> value, derivative;
};

inline MaskDerivative silhouette_derivative(const scene::TriangleMesh& m, const scene::Camera& cam,
                                            const float* direction, const geometry::TriangleNeighbors* nb = nullptr,
                                            const SilhouetteOptions& opt = {}) {
  using D = ad::Dual<float, 1>;
  const geometry::TriangleNeighbors own = nb ? geometry::TriangleNeighbors{} : geometry::TriangleNeighbors::build(m);
  const SilhouetteFrame f = prepare_silhouette(m, nb ? *nb : own, cam, opt);
  MaskDerivative out;
  out.value = coverage_mask(f.raster);
  out.derivative.assign(out.value.size(), 0.0f);
  ad::ParamSet set;
  set.buffers[0].values = m.positions.data();
  set.buffers[0].size = std::int32_t(m.positions.size());
  set.buffers[0].tangents[0] = direction;
  const ad::ParamSource pos{m.positions.data(), std::int32_t(m.positions.size()), 0};
  ad::ParamReader<D> reader(&set);
  for (const SilhouetteCrossing& c : f.crossings) {
    const PairCoverage<D> pc = crossing_coverage<D>(reader, pos, cam, c);
    out.value[std::size_t(c.other)] += pc.gain.value;
    out.value[std::size_t(c.covered)] -= pc.loss.value;
    out.derivative[std::size_t(c.other)] += pc.gain.grad[0];
    out.derivative[std::size_t(c.covered)] -= pc.loss.grad[0];
  }
  return out;
}

}  // namespace difftrans::render
