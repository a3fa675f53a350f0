// A float z-buffer rasterizer for silhouettes and screen-space terms: per
// pixel the closest triangle covering its centre, its depth and perspective-
// correct barycentrics, rows in parallel bands; and a supersampled coverage
// reference. No derivatives here: the edge anti-aliasing (silhouette.hpp) and
// the screen-space losses (losses/screen_smoothness.hpp) differentiate what
// the raster decides.
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

}  // namespace difftrans::render
