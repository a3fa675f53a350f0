// Shading-normal error of a predicted mesh against the ground truth: the
// angle between the normal the tracer shades a point with (the vertex normals,
// each the normalized sum of its faces' unit normals, interpolated by the
// barycentrics: scene::TriangleMesh) and the true surface's shading normal at
// the nearest of the truth's area-weighted samples. Refraction turns with the
// normal, not the position: a mesh within a fraction of a pixel of the truth
// can still tilt its normals by several degrees, and the index of refraction
// fitted on it then makes up for the wrong bending (docs/metrics.md,
// "Normal error"). Same frame and samples as evaluate_geometry.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "difftrans/io/mesh.hpp"
#include "difftrans/metrics/chamfer.hpp"
#include "difftrans/scene/mesh.hpp"

namespace difftrans::metrics {

struct NormalError {
  double mean_deg = 0.0;    // mean angle over the predicted mesh's samples
  double median_deg = 0.0;
  double p90_deg = 0.0;     // 90th percentile
  double rms_deg = 0.0;
  std::size_t samples = 0;
};

// The tracer's shading normal at each sample of `mesh` (unit length; the face
// normal where the interpolated vertex normals cancel).
inline std::vector<Vec3d> shading_normals_at(const io::Mesh& mesh, const std::vector<SurfaceSample>& samples) {
  const scene::TriangleMesh tm(io::flat_positions(mesh), io::flat_triangles(mesh));
  const auto vertex_normal = [&](std::int32_t v) {
    const float* n = tm.vertex_normals.data() + 3 * std::size_t(v);
    return Vec3d(n[0], n[1], n[2]);
  };
  std::vector<Vec3d> normals(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const SurfaceSample& s = samples[i];
    const Vec3i& f = mesh.triangles[s.triangle];
    Vec3d n = (1.0 - s.b1 - s.b2) * vertex_normal(f.x) + s.b1 * vertex_normal(f.y) + s.b2 * vertex_normal(f.z);
    double l = glm::length(n);
    if (!(l > 1e-12)) {
      const Vec3d a(mesh.positions[std::size_t(f.x)]), b(mesh.positions[std::size_t(f.y)]),
          c(mesh.positions[std::size_t(f.z)]);
      n = glm::cross(b - a, c - a);
      l = glm::length(n);
    }
    normals[i] = l > 0.0 ? n / l : Vec3d(0.0);
  }
  return normals;
}

// Statistics of the angles (degrees) of a list; throws on an empty one.
inline NormalError angle_statistics(std::vector<double> angles) {
  if (angles.empty()) throw std::invalid_argument("normal error: no samples");
  NormalError e;
  e.samples = angles.size();
  double sum = 0.0, sum2 = 0.0;
  for (const double a : angles) {
    sum += a;
    sum2 += a * a;
  }
  e.mean_deg = sum / double(angles.size());
  e.rms_deg = std::sqrt(sum2 / double(angles.size()));
  const auto quantile = [&](double q) {
    const std::size_t k = std::min(angles.size() - 1, std::size_t(q * double(angles.size())));
    std::nth_element(angles.begin(), angles.begin() + std::ptrdiff_t(k), angles.end());
    return angles[k];
  };
  e.median_deg = quantile(0.5);
  e.p90_deg = quantile(0.9);
  return e;
}

// The angle between the predicted mesh's shading normal and the truth's at
// the nearest true sample, over options.samples points of the predicted
// surface (options.tau is not used).
inline NormalError normal_error(const io::Mesh& predicted, const io::Mesh& truth, const GeometryOptions& options = {}) {
  const auto [p, q] = detail::metric_frame(predicted, truth, options);
  const std::vector<SurfaceSample> sp = sample_surface_at(p, options.samples, options.seed);
  const std::vector<SurfaceSample> sq = sample_surface_at(q, options.samples, options.seed);
  const std::vector<Vec3d> np = shading_normals_at(p, sp), nq = shading_normals_at(q, sq);
  std::vector<Vec3d> points_p(sp.size()), points_q(sq.size());
  for (std::size_t i = 0; i < sp.size(); ++i) points_p[i] = sp[i].point;
  for (std::size_t i = 0; i < sq.size(); ++i) points_q[i] = sq[i].point;
  const std::vector<Nearest> nearest = nearest_points(points_p, points_q, options.threads);
  std::vector<double> angles(sp.size());
  constexpr double degrees = 180.0 / 3.14159265358979323846;
  for (std::size_t i = 0; i < sp.size(); ++i)
    angles[i] = std::acos(std::clamp(glm::dot(np[i], nq[nearest[i].index]), -1.0, 1.0)) * degrees;
  return angle_statistics(std::move(angles));
}

}  // namespace difftrans::metrics
