// Geometry metrics of docs/metrics.md: both meshes normalized with the ground
// truth's unit-box transform, area-weighted point samples (fixed seed), nearest
// neighbours by k-d tree (nanoflann); Chamfer distance = mean_P d^2 + mean_Q d^2,
// F1 at tau = 2PR / (P + R).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

// after the standard headers: Debian 12's nanoflann uses std::uint32_t and
// std::size_t without including their headers, which GCC 13's library no
// longer brings in on the way
#include <nanoflann.hpp>

#include "difftrans/io/mesh.hpp"

namespace difftrans::metrics {

struct GeometryOptions {
  std::size_t samples = 200000;     // points per mesh
  std::uint64_t seed = 20240601;    // the fixed seed of the protocol's figures
  double tau = 0.01;                // F1 distance threshold, in the normalized frame
  bool normalize = true;            // apply the ground truth's unit-box transform to both
  unsigned threads = 0;             // nearest-neighbour queries; 0 = hardware concurrency
};

struct GeometryMetrics {
  double chamfer = 0.0;    // mean_P d^2 + mean_Q d^2
  double precision = 0.0;  // fraction of predicted points within tau of the ground truth
  double recall = 0.0;     // fraction of ground-truth points within tau of the prediction
  double f1 = 0.0;
  double tau = 0.0;
  std::size_t samples = 0;
};

namespace detail {

// Uniform double in [0, 1) from the top 53 bits: the same on every platform
// (std::uniform_real_distribution is not).
inline double uniform01(std::mt19937_64& rng) { return double(rng() >> 11) * 0x1.0p-53; }

struct PointCloud {
  const std::vector<Vec3d>& points;
  std::size_t kdtree_get_point_count() const { return points.size(); }
  double kdtree_get_pt(std::size_t i, std::size_t d) const { return points[i][int(d)]; }
  template <class Box> bool kdtree_get_bbox(Box&) const { return false; }
};

}  // namespace detail

// A point on a mesh's surface: where it lies, and on which triangle at which
// barycentrics (b1, b2) of its second and third corners.
struct SurfaceSample {
  Vec3d point{0.0};
  std::size_t triangle = 0;
  double b1 = 0.0, b2 = 0.0;
};

// n points uniformly distributed by area over the surface (triangle chosen by
// area, then a uniform point in it). Deterministic for a seed.
inline std::vector<SurfaceSample> sample_surface_at(const io::Mesh& mesh, std::size_t n, std::uint64_t seed) {
  std::vector<double> cdf(mesh.triangles.size());
  double total = 0.0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Vec3i& f = mesh.triangles[t];
    const Vec3d a(mesh.positions[size_t(f.x)]), b(mesh.positions[size_t(f.y)]), c(mesh.positions[size_t(f.z)]);
    total += 0.5 * glm::length(glm::cross(b - a, c - a));
    cdf[t] = total;
  }
  if (!(total > 0.0) || !std::isfinite(total))
    throw std::invalid_argument("sample_surface: the mesh has no surface area to sample");
  std::mt19937_64 rng(seed);
  std::vector<SurfaceSample> samples(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double pick = detail::uniform01(rng) * total;
    std::size_t t = std::size_t(std::upper_bound(cdf.begin(), cdf.end(), pick) - cdf.begin());
    t = std::min(t, cdf.size() - 1);
    const Vec3i& f = mesh.triangles[t];
    const double s = std::sqrt(detail::uniform01(rng)), r = detail::uniform01(rng);
    const double b1 = s * (1.0 - r), b2 = s * r;
    const Vec3d a(mesh.positions[size_t(f.x)]), b(mesh.positions[size_t(f.y)]), c(mesh.positions[size_t(f.z)]);
    samples[i] = {(1.0 - b1 - b2) * a + b1 * b + b2 * c, t, b1, b2};
  }
  return samples;
}

// The points of sample_surface_at alone.
inline std::vector<Vec3d> sample_surface(const io::Mesh& mesh, std::size_t n, std::uint64_t seed) {
  const std::vector<SurfaceSample> samples = sample_surface_at(mesh, n, seed);
  std::vector<Vec3d> points(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) points[i] = samples[i].point;
  return points;
}

// The nearest point of `points` to each query: its index and squared distance.
struct Nearest {
  std::uint32_t index = 0;
  double distance2 = 0.0;
};

inline std::vector<Nearest> nearest_points(const std::vector<Vec3d>& queries, const std::vector<Vec3d>& points,
                                           unsigned threads = 0) {
  if (points.empty()) throw std::invalid_argument("nearest_points: no points to search");
  using Cloud = detail::PointCloud;
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>, Cloud, 3, std::uint32_t>;
  const Cloud cloud{points};
  Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  std::vector<Nearest> out(queries.size());
  const auto work = [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      const double q[3] = {queries[i].x, queries[i].y, queries[i].z};
      tree.knnSearch(q, 1, &out[i].index, &out[i].distance2);
    }
  };
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  threads = unsigned(std::min<std::size_t>(threads, std::max<std::size_t>(1, queries.size() / 4096)));
  std::vector<std::thread> pool;
  const std::size_t chunk = (queries.size() + threads - 1) / threads;
  for (unsigned k = 1; k < threads; ++k)
    pool.emplace_back(work, std::min(queries.size(), k * chunk), std::min(queries.size(), (k + 1) * chunk));
  work(0, std::min(queries.size(), chunk));
  for (auto& t : pool) t.join();
  return out;
}

// Squared distance from each query to its nearest point of `points`.
inline std::vector<double> nearest_squared_distances(const std::vector<Vec3d>& queries,
                                                     const std::vector<Vec3d>& points, unsigned threads = 0) {
  if (points.empty()) throw std::invalid_argument("nearest_squared_distances: no points to search");
  const std::vector<Nearest> nearest = nearest_points(queries, points, threads);
  std::vector<double> out(nearest.size());
  for (std::size_t i = 0; i < nearest.size(); ++i) out[i] = nearest[i].distance2;
  return out;
}

// Chamfer distance, precision, recall and F1 of two point sets.
inline GeometryMetrics compare_point_sets(const std::vector<Vec3d>& predicted, const std::vector<Vec3d>& truth,
                                          double tau, unsigned threads = 0) {
  if (predicted.empty() || truth.empty()) throw std::invalid_argument("compare_point_sets: empty point set");
  const auto d_pred = nearest_squared_distances(predicted, truth, threads);
  const auto d_truth = nearest_squared_distances(truth, predicted, threads);
  GeometryMetrics m;
  m.tau = tau;
  m.samples = predicted.size();
  double sum_p = 0.0, sum_q = 0.0;
  std::size_t near_p = 0, near_q = 0;
  for (const double d2 : d_pred) {
    sum_p += d2;
    near_p += d2 < tau * tau;
  }
  for (const double d2 : d_truth) {
    sum_q += d2;
    near_q += d2 < tau * tau;
  }
  m.chamfer = sum_p / double(d_pred.size()) + sum_q / double(d_truth.size());
  m.precision = double(near_p) / double(d_pred.size());
  m.recall = double(near_q) / double(d_truth.size());
  m.f1 = m.precision + m.recall > 0.0 ? 2.0 * m.precision * m.recall / (m.precision + m.recall) : 0.0;
  return m;
}

// The protocol's geometry metrics of a predicted mesh against the ground truth.
namespace detail {

// Both meshes in the frame of the metrics: the truth's unit box when
// options.normalize, as given otherwise.
inline std::pair<io::Mesh, io::Mesh> metric_frame(const io::Mesh& predicted, const io::Mesh& truth,
                                                  const GeometryOptions& options) {
  std::pair<io::Mesh, io::Mesh> m{predicted, truth};
  if (options.normalize) {
    const io::UnitBoxTransform transform = io::unit_box_transform(truth);
    io::apply_transform(transform, m.first);
    io::apply_transform(transform, m.second);
  }
  return m;
}

}  // namespace detail

inline GeometryMetrics evaluate_geometry(const io::Mesh& predicted, const io::Mesh& truth,
                                         const GeometryOptions& options = {}) {
  const auto [p, q] = detail::metric_frame(predicted, truth, options);
  const auto points_p = sample_surface(p, options.samples, options.seed);
  const auto points_q = sample_surface(q, options.samples, options.seed);
  return compare_point_sets(points_p, points_q, options.tau, options.threads);
}

// Where the Chamfer distance lies along one axis of the metrics' frame: the
// truth's extent along `axis` (0 x, 1 y, 2 z) cut into `bands` equal slabs,
// each sample point of either mesh counted in the slab of its coordinate
// (clamped into the first or the last). The same samples as
// evaluate_geometry, so predicted[b] + truth[b] summed over the bands is its
// chamfer: a concavity the silhouettes cannot show, or a part a stage leaves
// alone, shows as the bands that hold most of it.
struct ChamferBands {
  int axis = 1;
  double from = 0.0, to = 0.0;          // the slabs' extent along the axis
  std::vector<double> predicted, truth;  // band b's part of mean_P d^2 and of mean_Q d^2
};

inline ChamferBands chamfer_bands(const io::Mesh& predicted, const io::Mesh& truth, int axis, int bands,
                                  const GeometryOptions& options = {}) {
  if (axis < 0 || axis > 2) throw std::invalid_argument("chamfer_bands: the axis is 0, 1 or 2");
  if (bands < 1) throw std::invalid_argument("chamfer_bands: at least one band");
  const auto [p, q] = detail::metric_frame(predicted, truth, options);
  const auto points_p = sample_surface(p, options.samples, options.seed);
  const auto points_q = sample_surface(q, options.samples, options.seed);
  ChamferBands out;
  out.axis = axis;
  out.from = std::numeric_limits<double>::infinity();
  out.to = -std::numeric_limits<double>::infinity();
  for (const Vec3d& x : points_q) out.from = std::min(out.from, x[axis]), out.to = std::max(out.to, x[axis]);
  const double width = out.to > out.from ? (out.to - out.from) / double(bands) : 1.0;
  const auto band = [&](const Vec3d& x) {
    const double t = std::floor((x[axis] - out.from) / width);
    return std::size_t(std::clamp(t, 0.0, double(bands - 1)));
  };
  const auto accumulate = [&](const std::vector<Vec3d>& from, const std::vector<Vec3d>& to, std::vector<double>& sums) {
    sums.assign(std::size_t(bands), 0.0);
    const std::vector<double> d = nearest_squared_distances(from, to, options.threads);
    for (std::size_t i = 0; i < d.size(); ++i) sums[band(from[i])] += d[i];
    for (double& s : sums) s /= double(d.size());
  };
  accumulate(points_p, points_q, out.predicted);
  accumulate(points_q, points_p, out.truth);
  return out;
}

// An error map: the distance from each vertex of `predicted` to the truth's
// surface, in the same frame as evaluate_geometry (the truth's unit box when
// options.normalize), the surface standing as its options.samples
// area-weighted points (so a vertex on the surface reads about the samples'
// spacing, not 0).
inline std::vector<double> vertex_distances(const io::Mesh& predicted, const io::Mesh& truth,
                                            const GeometryOptions& options = {}) {
  const auto [p, q] = detail::metric_frame(predicted, truth, options);
  std::vector<Vec3d> vertices(p.positions.size());
  for (std::size_t v = 0; v < vertices.size(); ++v) vertices[v] = Vec3d(p.positions[v]);
  std::vector<double> d = nearest_squared_distances(vertices, sample_surface(q, options.samples, options.seed),
                                                    options.threads);
  for (double& x : d) x = std::sqrt(x);
  return d;
}

}  // namespace difftrans::metrics
