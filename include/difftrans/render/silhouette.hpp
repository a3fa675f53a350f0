// Differentiable silhouettes for stage 1: a float z-buffer rasterizer (triangle id, depth, barycentrics per
// pixel), nvdiffrast-style analytic anti-aliasing of the coverage mask with gradients to vertex positions,
// and depth / normal maps with the screen-space smoothness term (|∇d| + |∇n| + |∇²n|).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/params.hpp"
#include "difftrans/core/parallel.hpp"
#include "difftrans/scene/camera.hpp"
#include "difftrans/scene/mesh.hpp"

namespace difftrans::render {

// ------------------------------------------------------------------ topology

// For every triangle edge k (vertices k and k+1 mod 3) the triangle across it:
// >= 0 the one other triangle sharing that (undirected) edge, -1 none (a
// boundary edge), -2 more than one (non-manifold: always a silhouette edge).
struct TriangleNeighbors {
  static constexpr std::int32_t boundary = -1, non_manifold = -2;
  std::vector<std::int32_t> across;  // 3 per triangle

  static TriangleNeighbors build(const std::int32_t* triangles, std::int32_t num_triangles) {
    TriangleNeighbors n;
    n.across.assign(std::size_t(3) * std::size_t(num_triangles), boundary);
    struct Half {
      std::uint64_t key;
      std::int32_t slot;  // 3 * triangle + k
    };
    std::vector<Half> halves;
    halves.reserve(n.across.size());
    for (std::int32_t t = 0; t < num_triangles; ++t)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = std::uint32_t(triangles[3 * t + k]), b = std::uint32_t(triangles[3 * t + (k + 1) % 3]);
        if (a == b) continue;  // a collapsed edge joins nothing
        const std::uint64_t key = (std::uint64_t(std::min(a, b)) << 32) | std::uint64_t(std::max(a, b));
        halves.push_back(Half{key, 3 * t + k});
      }
    std::sort(halves.begin(), halves.end(), [](const Half& x, const Half& y) {
      return x.key < y.key || (x.key == y.key && x.slot < y.slot);
    });
    for (std::size_t i = 0; i < halves.size();) {
      std::size_t j = i + 1;
      while (j < halves.size() && halves[j].key == halves[i].key) ++j;
      if (j - i == 2) {
        n.across[std::size_t(halves[i].slot)] = halves[i + 1].slot / 3;
        n.across[std::size_t(halves[i + 1].slot)] = halves[i].slot / 3;
      } else if (j - i > 2) {
        for (std::size_t k = i; k < j; ++k) n.across[std::size_t(halves[k].slot)] = non_manifold;
      }
      i = j;
    }
    return n;
  }
  static TriangleNeighbors build(const scene::TriangleMesh& m) { return build(m.triangles.data(), m.num_triangles()); }
};

// ------------------------------------------------------------------ rasterizer

struct RasterOptions {
  // Triangles with a vertex at view depth <= near are rejected (not clipped):
  // stage 1 looks at an object well inside the camera's view.
  float near = 1e-3f;
  int band_rows = 8;  // rows per parallel work item (each band owns its pixels)
};

// Pixel (x, y) is entry y * width + x (row 0 at the top, Camera convention).
struct Raster {
  int width = 0, height = 0;
  std::vector<std::int32_t> triangle;  // closest triangle covering the pixel centre, or -1
  std::vector<float> depth;            // its view depth there (-z in camera space); +inf for background
  std::vector<float> b1, b2;           // perspective-correct barycentrics of its vertices 1 and 2
  // Every vertex projected: continuous pixel coordinates and view depth;
  // vertex_depth <= near marks a vertex that is not drawn.
  std::vector<Vec2f> screen;
  std::vector<float> vertex_depth;
  float near = 0.0f;

  std::int64_t pixels() const { return std::int64_t(width) * height; }
  bool covered(std::int64_t p) const { return triangle[std::size_t(p)] >= 0; }
};

namespace detail {

inline float cross2(const Vec2f& a, const Vec2f& b) { return a.x * b.y - a.y * b.x; }

// Projects every vertex (in parallel) into r.screen / r.vertex_depth.
inline void project_vertices(const float* positions, std::int32_t num_vertices, const scene::Camera& cam, float near,
                             Raster& r) {
  r.screen.assign(std::size_t(num_vertices), Vec2f(0.0f));
  r.vertex_depth.assign(std::size_t(num_vertices), 0.0f);
  r.near = near;
  parallel_for(num_vertices, 4096, [&](std::int64_t b, std::int64_t e, int) {
    for (std::int64_t v = b; v < e; ++v) {
      const Vec3f p(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
      const scene::Projection<float> q = cam.project(p);
      const bool ok = q.valid && q.depth > near && std::isfinite(q.pixel.x) && std::isfinite(q.pixel.y);
      r.screen[std::size_t(v)] = ok ? q.pixel : Vec2f(0.0f);
      r.vertex_depth[std::size_t(v)] = ok ? q.depth : 0.0f;
    }
  });
}

// Whether triangle t is drawn: its vertices lie beyond `near` and its projection has a non-zero area.
inline bool drawable(const Raster& r, const std::int32_t* tri) {
  for (int k = 0; k < 3; ++k)
    if (!(r.vertex_depth[std::size_t(tri[k])] > r.near)) return false;
  const Vec2f a = r.screen[std::size_t(tri[0])], b = r.screen[std::size_t(tri[1])], c = r.screen[std::size_t(tri[2])];
  const float area = cross2(b - a, c - a);
  return area != 0.0f && std::isfinite(area);
}

// Calls visit(worker, t, y0, y1) for every drawable triangle t over the rows
// [y0, y1) of each band it touches; bands run in parallel, a band's pixels are
// only written by the worker running it. Triangles come in increasing id.
template <class Visit>
void for_each_band(const Raster& r, const std::int32_t* triangles, std::int32_t num_triangles, int band_rows,
                   Visit&& visit) {
  band_rows = std::max(1, band_rows);
  const int bands = (r.height + band_rows - 1) / band_rows;
  if (bands <= 0 || r.width <= 0) return;
  std::vector<std::vector<std::int32_t>> bins(static_cast<std::size_t>(bands));
  for (std::int32_t t = 0; t < num_triangles; ++t) {
    const std::int32_t* tri = triangles + 3 * t;
    if (!drawable(r, tri)) continue;
    float lo = r.screen[std::size_t(tri[0])].y, hi = lo;
    for (int k = 1; k < 3; ++k) {
      lo = std::min(lo, r.screen[std::size_t(tri[k])].y);
      hi = std::max(hi, r.screen[std::size_t(tri[k])].y);
    }
    // rows whose centre y + 0.5 lies in [lo, hi]
    const int y0 = std::max(0, int(std::ceil(std::max(lo - 0.5f, -1.0f))));
    const int y1 = std::min(r.height - 1, int(std::floor(std::min(hi - 0.5f, float(r.height)))));
    if (y0 > y1) continue;
    for (int b = y0 / band_rows; b <= y1 / band_rows; ++b) bins[std::size_t(b)].push_back(t);
  }
  parallel_for(bands, 1, [&](std::int64_t b0, std::int64_t b1, int worker) {
    for (std::int64_t b = b0; b < b1; ++b) {
      const int ya = int(b) * band_rows, yb = std::min(r.height, ya + band_rows);
      for (std::int32_t t : bins[std::size_t(b)]) visit(worker, t, ya, yb);
    }
  });
}

// Calls cover(x, y, l0, l1, l2) for every pixel of rows [ya, yb) whose centre
// lies in the (drawable) triangle, inside or on its edges, with the
// screen-space barycentrics. A centre on an edge shared by two triangles is
// covered by both (the edge functions are exact negations), so no cracks.
template <class Cover>
void scan_triangle(const Raster& r, const std::int32_t* tri, int ya, int yb, Cover&& cover) {
  const Vec2f a = r.screen[std::size_t(tri[0])], b = r.screen[std::size_t(tri[1])], c = r.screen[std::size_t(tri[2])];
  const float area = cross2(b - a, c - a);
  const float inv = 1.0f / area;
  const float lo_y = std::min(a.y, std::min(b.y, c.y)), hi_y = std::max(a.y, std::max(b.y, c.y));
  const float lo_x = std::min(a.x, std::min(b.x, c.x)), hi_x = std::max(a.x, std::max(b.x, c.x));
  const int y0 = std::max(ya, int(std::ceil(std::max(lo_y - 0.5f, -1.0f))));
  const int y1 = std::min(yb - 1, int(std::floor(std::min(hi_y - 0.5f, float(r.height)))));
  const int x0 = std::max(0, int(std::ceil(std::max(lo_x - 0.5f, -1.0f))));
  const int x1 = std::min(r.width - 1, int(std::floor(std::min(hi_x - 0.5f, float(r.width)))));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const Vec2f p(float(x) + 0.5f, float(y) + 0.5f);
      const float w0 = cross2(b - p, c - p), w1 = cross2(c - p, a - p), w2 = cross2(a - p, b - p);
      const bool inside = area > 0.0f ? (w0 >= 0.0f && w1 >= 0.0f && w2 >= 0.0f) : (w0 <= 0.0f && w1 <= 0.0f && w2 <= 0.0f);
      if (inside) cover(x, y, w0 * inv, w1 * inv, w2 * inv);
    }
}

}  // namespace detail

// Rasterizes the mesh (positions 3 per vertex, triangles 3 per face) into the
// camera: per pixel the closest triangle covering its centre (ties: the lower
// id), its depth and perspective-correct barycentrics. Both windings are drawn.
inline Raster rasterize(const float* positions, std::int32_t num_vertices, const std::int32_t* triangles,
                        std::int32_t num_triangles, const scene::Camera& cam, const RasterOptions& opt = {}) {
  Raster r;
  r.width = cam.width;
  r.height = cam.height;
  const std::size_t n = std::size_t(r.pixels());
  r.triangle.assign(n, -1);
  r.depth.assign(n, std::numeric_limits<float>::infinity());
  r.b1.assign(n, 0.0f);
  r.b2.assign(n, 0.0f);
  detail::project_vertices(positions, num_vertices, cam, opt.near, r);
  detail::for_each_band(r, triangles, num_triangles, opt.band_rows, [&](int, std::int32_t t, int ya, int yb) {
    const std::int32_t* tri = triangles + 3 * t;
    const float iz0 = 1.0f / r.vertex_depth[std::size_t(tri[0])], iz1 = 1.0f / r.vertex_depth[std::size_t(tri[1])],
                iz2 = 1.0f / r.vertex_depth[std::size_t(tri[2])];
    detail::scan_triangle(r, tri, ya, yb, [&](int x, int y, float l0, float l1, float l2) {
      const float q0 = l0 * iz0, q1 = l1 * iz1, q2 = l2 * iz2;
      const float inv_depth = q0 + q1 + q2;
      const float depth = 1.0f / inv_depth;
      const std::size_t p = std::size_t(y) * std::size_t(r.width) + std::size_t(x);
      if (!(depth < r.depth[p])) return;  // equal depth: the earlier (lower) id stays
      r.depth[p] = depth;
      r.triangle[p] = t;
      r.b1[p] = q1 * depth;
      r.b2[p] = q2 * depth;
    });
  });
  return r;
}

inline Raster rasterize(const scene::TriangleMesh& m, const scene::Camera& cam, const RasterOptions& opt = {}) {
  return rasterize(m.positions.data(), m.num_vertices(), m.triangles.data(), m.num_triangles(), cam, opt);
}

// Reference coverage: the fraction of n×n sub-pixel sample points (centres of
// an n×n grid) covered by any triangle, per pixel (width·height values).
inline std::vector<float> supersampled_coverage(const scene::TriangleMesh& m, const scene::Camera& cam, int n,
                                                const RasterOptions& opt = {}) {
  scene::Camera fine = cam;
  fine.fx *= float(n);
  fine.fy *= float(n);
  fine.cx *= float(n);
  fine.cy *= float(n);
  fine.width = cam.width * n;
  fine.height = cam.height * n;
  Raster r;
  r.width = fine.width;
  r.height = fine.height;
  detail::project_vertices(m.positions.data(), m.num_vertices(), fine, opt.near, r);
  std::vector<unsigned char> hit(std::size_t(r.pixels()), 0);
  const int band = std::max(opt.band_rows, n);
  detail::for_each_band(r, m.triangles.data(), m.num_triangles(), band, [&](int, std::int32_t t, int ya, int yb) {
    detail::scan_triangle(r, m.triangles.data() + 3 * t, ya, yb, [&](int x, int y, float, float, float) {
      hit[std::size_t(y) * std::size_t(r.width) + std::size_t(x)] = 1;
    });
  });
  std::vector<float> cov(std::size_t(cam.width) * std::size_t(cam.height), 0.0f);
  const float w = 1.0f / float(n * n);
  parallel_for(cam.height, 4, [&](std::int64_t y0, std::int64_t y1, int) {
    for (std::int64_t y = y0; y < y1; ++y)
      for (int x = 0; x < cam.width; ++x) {
        int count = 0;
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i)
            count += hit[(std::size_t(y) * n + j) * std::size_t(r.width) + std::size_t(x) * n + i];
        cov[std::size_t(y) * cam.width + x] = float(count) * w;
      }
  });
  return cov;
}

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
DT_HOST_DEVICE PairCoverage<S> crossing_coverage(Reader& reader, const scene::ParamSource& positions,
                                                 const scene::Camera& cam, const SilhouetteCrossing& c) {
  const scene::Projection<S> a = cam.project(scene::load3<S>(reader, positions, c.v0));
  const scene::Projection<S> b = cam.project(scene::load3<S>(reader, positions, c.v1));
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
                                                      const TriangleNeighbors& nb, int max_walk = 64) {
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

inline SilhouetteFrame prepare_silhouette(const scene::TriangleMesh& m, const TriangleNeighbors& nb,
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
  const scene::ParamSource pos{m.positions.data(), std::int32_t(m.positions.size()), -1};
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
                               const TriangleNeighbors* nb = nullptr, const SilhouetteOptions& opt = {}) {
  const TriangleNeighbors own = nb ? TriangleNeighbors{} : TriangleNeighbors::build(m);
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
// small tape per crossing (two vertices, six leaves), scattered atomically.
inline void silhouette_backward(const SilhouetteFrame& f, const scene::TriangleMesh& m, const scene::Camera& cam,
                                const float* mask_adjoint, float* grad_positions) {
  using V = ad::Var<float>;
  ad::ParamSet set;
  set.buffers[0].values = m.positions.data();
  set.buffers[0].size = std::int32_t(m.positions.size());
  set.buffers[0].gradient = grad_positions;
  const scene::ParamSource pos{m.positions.data(), std::int32_t(m.positions.size()), 0};
  parallel_for(std::int64_t(f.crossings.size()), 256, [&](std::int64_t b, std::int64_t e, int) {
    ad::Tape<float> tape(256);
    ad::LeafRecord log[8];
    ad::ParamReader<V> reader(&set, &tape, log, 8);
    for (std::int64_t i = b; i < e; ++i) {
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
  });
}

// The same from scratch (rasterize, find crossings, backward); returns the mask.
inline std::vector<float> silhouette_gradient(const scene::TriangleMesh& m, const scene::Camera& cam,
                                              const float* mask_adjoint, float* grad_positions,
                                              const TriangleNeighbors* nb = nullptr,
                                              const SilhouetteOptions& opt = {}, SilhouetteStats* stats = nullptr) {
  const TriangleNeighbors own = nb ? TriangleNeighbors{} : TriangleNeighbors::build(m);
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
                                            const float* direction, const TriangleNeighbors* nb = nullptr,
                                            const SilhouetteOptions& opt = {}) {
  using D = ad::Dual<float, 1>;
  const TriangleNeighbors own = nb ? TriangleNeighbors{} : TriangleNeighbors::build(m);
  const SilhouetteFrame f = prepare_silhouette(m, nb ? *nb : own, cam, opt);
  MaskDerivative out;
  out.value = coverage_mask(f.raster);
  out.derivative.assign(out.value.size(), 0.0f);
  ad::ParamSet set;
  set.buffers[0].values = m.positions.data();
  set.buffers[0].size = std::int32_t(m.positions.size());
  set.buffers[0].tangents[0] = direction;
  const scene::ParamSource pos{m.positions.data(), std::int32_t(m.positions.size()), 0};
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

// ------------------------------------------------------------------ mask loss

// Mean absolute difference between a mask and a target; when `adjoint` is
// given, writes the subgradient sign(mask - target) / N per pixel (0 where equal).
inline double mask_l1(const std::vector<float>& mask, const float* target, float* adjoint = nullptr) {
  const std::size_t n = mask.size();
  if (n == 0) return 0.0;
  double sum = 0.0;
  const float inv = 1.0f / float(n);
  for (std::size_t p = 0; p < n; ++p) {
    const float d = mask[p] - target[p];
    sum += std::fabs(double(d));
    if (adjoint) adjoint[p] = d > 0.0f ? inv : (d < 0.0f ? -inv : 0.0f);
  }
  return sum / double(n);
}

// ------------------------------------------------------------------ depth, normals, smoothness

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

inline GeometryMaps geometry_maps(const scene::TriangleMesh& m, const scene::Camera& cam, const Raster& r,
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
inline void geometry_backward(const scene::TriangleMesh& m, const scene::Camera& cam, const Raster& r,
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
  parallel_for(r.pixels(), 256, [&](std::int64_t b, std::int64_t e, int) {
    ad::Tape<float> tape(1 << 10);
    std::vector<ad::LeafRecord> log(64);
    ad::ParamReader<V> reader(&set, &tape, log.data(), std::int32_t(log.size()));
    for (std::int64_t p = b; p < e; ++p) {
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
  });
  m.normals_backward(grad_normals.data(), grad_positions);
}

// The smoothness loss of a mesh in a camera and, when grad_positions is given,
// its gradient w.r.t. the vertex positions added there (geometry_backward of
// the loss's adjoints). The maps are returned through maps_out when given.
inline double smoothness_gradient(const scene::TriangleMesh& m, const scene::Camera& cam, float* grad_positions,
                                  const SmoothnessOptions& opt = {}, const RasterOptions& ropt = {},
                                  GeometryMaps* maps_out = nullptr) {
  const Raster r = rasterize(m, cam, ropt);
  GeometryMaps g = geometry_maps(m, cam, r, opt);
  std::vector<float> ad_depth(g.depth.size()), ad_normal(g.normal.size());
  const double loss = smoothness_loss(g, opt, ad_depth.data(), ad_normal.data());
  if (grad_positions) geometry_backward(m, cam, r, ad_depth.data(), ad_normal.data(), grad_positions, opt);
  if (maps_out) *maps_out = std::move(g);
  return loss;
}

}  // namespace difftrans::render
