// Absorption error of docs/metrics.md: how far a fitted absorption field is
// from the true one inside the true object, where light can meet it. Points
// of a regular lattice over the true mesh's bounding box that lie inside the
// mesh (interior_points) are where both fields are compared; per channel c,
//
//   relative error_c = mean |σ_fit,c(x) − σ_true,c(x)| / mean σ_true,c(x)
//
// over those points, and the figure quoted is the mean of the three
// channels whose true mean is above 1e-6 (a clear channel has no relative
// error: its mean absolute error is reported instead).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/io/presets.hpp"
#include "difftrans/metrics/chamfer.hpp"

namespace difftrans::metrics {

// The points of a res³ lattice over the bounding box of a closed mesh that
// lie inside it: along each lattice line parallel to x the mesh's crossings
// are found (each triangle only against the lines its y-z extent covers)
// and the points between the first and second, third and fourth … crossing
// are inside. The lattice is offset by an irrational fraction of a cell so
// that no line runs through a vertex or an edge of a mesh made on a grid.
inline std::vector<Vec3f> interior_points(const std::vector<Vec3f>& positions, const std::vector<Vec3i>& triangles,
                                          int res) {
  if (res < 1) throw std::invalid_argument("interior_points: the lattice needs at least one point per axis");
  if (positions.empty() || triangles.empty()) return {};
  Vec3d lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (const Vec3f& p : positions) {
    lo = glm::min(lo, Vec3d(p));
    hi = glm::max(hi, Vec3d(p));
  }
  const Vec3d cell = (hi - lo) / double(res);
  const Vec3d offset(0.5 + 0.0618034, 0.5 + 0.0414214, 0.5 + 0.0236068);  // of a cell
  const auto coord = [&](int axis, int i) { return lo[axis] + (double(i) + offset[axis]) * cell[axis]; };
  std::vector<std::vector<double>> crossings(std::size_t(res) * std::size_t(res));
  for (const Vec3i& t : triangles) {
    const Vec3d a(positions[std::size_t(t.x)]), b(positions[std::size_t(t.y)]), c(positions[std::size_t(t.z)]);
    const double ymin = std::min({a.y, b.y, c.y}), ymax = std::max({a.y, b.y, c.y});
    const double zmin = std::min({a.z, b.z, c.z}), zmax = std::max({a.z, b.z, c.z});
    if (!(cell.y > 0.0 && cell.z > 0.0)) continue;
    const int j0 = std::max(0, int(std::floor((ymin - lo.y) / cell.y - offset.y)));
    const int j1 = std::min(res - 1, int(std::ceil((ymax - lo.y) / cell.y - offset.y)));
    const int k0 = std::max(0, int(std::floor((zmin - lo.z) / cell.z - offset.z)));
    const int k1 = std::min(res - 1, int(std::ceil((zmax - lo.z) / cell.z - offset.z)));
    // barycentrics of (y, z) in the triangle's projection on the y-z plane
    const double det = (b.y - a.y) * (c.z - a.z) - (c.y - a.y) * (b.z - a.z);
    if (det == 0.0) continue;  // edge-on: the lines graze it
    for (int k = k0; k <= k1; ++k)
      for (int j = j0; j <= j1; ++j) {
        const double y = coord(1, j), z = coord(2, k);
        const double u = ((y - a.y) * (c.z - a.z) - (c.y - a.y) * (z - a.z)) / det;
        const double v = ((b.y - a.y) * (z - a.z) - (y - a.y) * (b.z - a.z)) / det;
        if (u < 0.0 || v < 0.0 || u + v > 1.0) continue;
        crossings[std::size_t(k) * std::size_t(res) + std::size_t(j)].push_back(a.x + u * (b.x - a.x) +
                                                                                 v * (c.x - a.x));
      }
  }
  std::vector<Vec3f> inside;
  for (int k = 0; k < res; ++k)
    for (int j = 0; j < res; ++j) {
      std::vector<double>& xs = crossings[std::size_t(k) * std::size_t(res) + std::size_t(j)];
      std::sort(xs.begin(), xs.end());
      for (int i = 0; i < res; ++i) {
        const double x = coord(0, i);
        const std::size_t before = std::size_t(std::lower_bound(xs.begin(), xs.end(), x) - xs.begin());
        if (before % 2 == 1) inside.push_back(Vec3f(Vec3d(x, coord(1, j), coord(2, k))));
      }
    }
  return inside;
}

// σ of a grid at p, trilinear between its vertices (clamped to its box).
inline Vec3f grid_sigma_at(const io::AbsorptionGrid& g, const Vec3f& p) {
  Vec3f s(0.0f);
  if (g.sigma.size() < g.vertex_count() * 3 || g.res.x < 2 || g.res.y < 2 || g.res.z < 2) return s;
  int i0[3];
  float f[3];
  for (int a = 0; a < 3; ++a) {
    const float x = std::clamp((p[a] - g.lo[a]) / (g.hi[a] - g.lo[a]), 0.0f, 1.0f) * float(g.res[a] - 1);
    i0[a] = std::min(int(x), g.res[a] - 2);
    f[a] = x - float(i0[a]);
  }
  for (int corner = 0; corner < 8; ++corner) {
    const int di = corner & 1, dj = (corner >> 1) & 1, dk = (corner >> 2) & 1;
    const float w = (di ? f[0] : 1.0f - f[0]) * (dj ? f[1] : 1.0f - f[1]) * (dk ? f[2] : 1.0f - f[2]);
    for (int c = 0; c < 3; ++c) s[c] += w * g.sigma[g.index(i0[0] + di, i0[1] + dj, i0[2] + dk, c)];
  }
  return s;
}

struct AbsorptionError {
  std::size_t points = 0;                 // lattice points inside the true mesh
  std::array<double, 3> mean_true{}, mean_fit{}, mean_abs{}, relative{};  // per channel
  double mean_relative = 0.0;             // over the channels with a true mean above 1e-6 (0 if none)
};

// fit, truth: callables Vec3f -> Vec3f (σ per unit length at a point).
template <class Fit, class Truth>
AbsorptionError absorption_error(const std::vector<Vec3f>& points, const Fit& fit, const Truth& truth) {
  AbsorptionError e;
  e.points = points.size();
  if (points.empty()) return e;
  for (const Vec3f& p : points) {
    const Vec3f f = fit(p), t = truth(p);
    for (int c = 0; c < 3; ++c) {
      e.mean_true[std::size_t(c)] += double(t[c]);
      e.mean_fit[std::size_t(c)] += double(f[c]);
      e.mean_abs[std::size_t(c)] += std::abs(double(f[c]) - double(t[c]));
    }
  }
  int counted = 0;
  for (std::size_t c = 0; c < 3; ++c) {
    e.mean_true[c] /= double(points.size());
    e.mean_fit[c] /= double(points.size());
    e.mean_abs[c] /= double(points.size());
    e.relative[c] = e.mean_true[c] > 1e-6 ? e.mean_abs[c] / e.mean_true[c] : 0.0;
    if (e.mean_true[c] > 1e-6) {
      e.mean_relative += e.relative[c];
      ++counted;
    }
  }
  if (counted) e.mean_relative /= double(counted);
  return e;
}

// Where the absorption error lies along one axis: the points cut into
// equal slabs of their extent along it (slabs_over), and per slab the
// number of points and the mean true and fitted σ per channel. A band fitted
// too pale, a part too dark, or a part no ray reached, shows as the slabs
// where the two means part; the points-weighted mean of a column over the
// slabs is the whole field's mean (AbsorptionError::mean_true, mean_fit).
struct AbsorptionSlabs {
  Slabs slabs;
  std::vector<std::size_t> points;                // per slab
  std::vector<std::array<double, 3>> mean_true, mean_fit;  // per slab, per channel (0 in an empty slab)
};

template <class Fit, class Truth>
AbsorptionSlabs absorption_slabs(const std::vector<Vec3f>& points, const Fit& fit, const Truth& truth, int axis,
                                 int count) {
  AbsorptionSlabs out;
  out.slabs = slabs_over(points, axis, count);
  const std::size_t n = std::size_t(count);
  out.points.assign(n, 0);
  out.mean_true.assign(n, std::array<double, 3>{});
  out.mean_fit.assign(n, std::array<double, 3>{});
  for (const Vec3f& p : points) {
    const std::size_t b = std::size_t(out.slabs.of(double(p[axis])));
    const Vec3f f = fit(p), t = truth(p);
    ++out.points[b];
    for (int c = 0; c < 3; ++c) {
      out.mean_true[b][std::size_t(c)] += double(t[c]);
      out.mean_fit[b][std::size_t(c)] += double(f[c]);
    }
  }
  for (std::size_t b = 0; b < n; ++b)
    for (std::size_t c = 0; c < 3; ++c)
      if (out.points[b]) {
        out.mean_true[b][c] /= double(out.points[b]);
        out.mean_fit[b][c] /= double(out.points[b]);
      }
  return out;
}

}  // namespace difftrans::metrics
