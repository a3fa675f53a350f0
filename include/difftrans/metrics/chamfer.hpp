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
#include <string>
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

// Two point sets, each point with the squared distance to its nearest
// point of the other: what the Chamfer distance, the F1 and their split by
// region (chamfer_bands) are all computed from, so one nearest-neighbour
// search serves them all.
struct MatchedPoints {
  std::vector<Vec3d> predicted, truth;
  std::vector<double> predicted_d2, truth_d2;  // predicted[i] to the truth's nearest, truth[j] to the prediction's
};

inline MatchedPoints match_points(std::vector<Vec3d> predicted, std::vector<Vec3d> truth, unsigned threads = 0) {
  if (predicted.empty() || truth.empty()) throw std::invalid_argument("match_points: empty point set");
  MatchedPoints m;
  m.predicted_d2 = nearest_squared_distances(predicted, truth, threads);
  m.truth_d2 = nearest_squared_distances(truth, predicted, threads);
  m.predicted = std::move(predicted);
  m.truth = std::move(truth);
  return m;
}

// Chamfer distance, precision, recall and F1 of matched point sets.
inline GeometryMetrics compare_matched(const MatchedPoints& m, double tau) {
  if (m.predicted_d2.empty() || m.truth_d2.empty()) throw std::invalid_argument("compare_matched: empty point set");
  GeometryMetrics out;
  out.tau = tau;
  out.samples = m.predicted_d2.size();
  double sum_p = 0.0, sum_q = 0.0;
  std::size_t near_p = 0, near_q = 0;
  for (const double d2 : m.predicted_d2) {
    sum_p += d2;
    near_p += d2 < tau * tau;
  }
  for (const double d2 : m.truth_d2) {
    sum_q += d2;
    near_q += d2 < tau * tau;
  }
  out.chamfer = sum_p / double(m.predicted_d2.size()) + sum_q / double(m.truth_d2.size());
  out.precision = double(near_p) / double(m.predicted_d2.size());
  out.recall = double(near_q) / double(m.truth_d2.size());
  out.f1 = out.precision + out.recall > 0.0 ? 2.0 * out.precision * out.recall / (out.precision + out.recall) : 0.0;
  return out;
}

// Chamfer distance, precision, recall and F1 of two point sets.
inline GeometryMetrics compare_point_sets(const std::vector<Vec3d>& predicted, const std::vector<Vec3d>& truth,
                                          double tau, unsigned threads = 0) {
  if (predicted.empty() || truth.empty()) throw std::invalid_argument("compare_point_sets: empty point set");
  return compare_matched(match_points(predicted, truth, threads), tau);
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

// options.samples area-weighted points of each mesh (in the metrics' frame),
// matched: the samples behind evaluate_geometry.
inline MatchedPoints match_samples(const io::Mesh& predicted, const io::Mesh& truth, const GeometryOptions& options = {}) {
  const auto [p, q] = detail::metric_frame(predicted, truth, options);
  return match_points(sample_surface(p, options.samples, options.seed), sample_surface(q, options.samples, options.seed),
                      options.threads);
}

inline GeometryMetrics evaluate_geometry(const io::Mesh& predicted, const io::Mesh& truth,
                                         const GeometryOptions& options = {}) {
  return compare_matched(match_samples(predicted, truth, options), options.tau);
}

// `count` equal slabs of an extent along one axis (0 x, 1 y, 2 z); a
// coordinate outside the extent falls into the first or the last slab.
struct Slabs {
  int axis = 1, count = 1;
  double from = 0.0, to = 0.0;
  double width() const { return to > from ? (to - from) / double(count) : 1.0; }
  double lower(int b) const { return from + width() * double(b); }
  double upper(int b) const { return from + width() * double(b + 1); }
  int of(double coordinate) const {
    return int(std::clamp(std::floor((coordinate - from) / width()), 0.0, double(count - 1)));
  }
};

// The slabs over the extent of `points` (anything indexed [0..2]) along axis.
template <class Point>
Slabs slabs_over(const std::vector<Point>& points, int axis, int count) {
  if (axis < 0 || axis > 2) throw std::invalid_argument("slabs_over: the axis is 0, 1 or 2");
  if (count < 1) throw std::invalid_argument("slabs_over: at least one slab");
  Slabs s;
  s.axis = axis;
  s.count = count;
  s.from = std::numeric_limits<double>::infinity();
  s.to = -std::numeric_limits<double>::infinity();
  for (const Point& x : points) s.from = std::min(s.from, double(x[axis])), s.to = std::max(s.to, double(x[axis]));
  if (points.empty()) s.from = s.to = 0.0;
  return s;
}

// An axis by its name: "x", "y" or "z" to 0, 1 or 2.
inline int axis_index(const std::string& name) {
  if (name == "x") return 0;
  if (name == "y") return 1;
  if (name == "z") return 2;
  throw std::invalid_argument("axis_index: '" + name + "' is not x, y or z");
}

// Where the Chamfer distance lies along one axis of the metrics' frame: the
// truth's extent along the axis cut into equal slabs, each sample point of
// either mesh counted in the slab of its coordinate. Made from the matched
// samples of evaluate_geometry, so predicted[b] + truth[b] summed over the
// slabs is its chamfer: a concavity the silhouettes cannot show, or a part a
// stage leaves alone, shows as the slabs that hold most of it.
struct ChamferBands {
  Slabs slabs;
  std::vector<double> predicted, truth;  // slab b's part of mean_P d^2 and of mean_Q d^2
};

inline ChamferBands chamfer_bands(const MatchedPoints& m, const Slabs& slabs) {
  ChamferBands out;
  out.slabs = slabs;
  const auto accumulate = [&](const std::vector<Vec3d>& points, const std::vector<double>& d2, std::vector<double>& sums) {
    sums.assign(std::size_t(slabs.count), 0.0);
    for (std::size_t i = 0; i < d2.size(); ++i) sums[std::size_t(slabs.of(points[i][slabs.axis]))] += d2[i];
    for (double& s : sums) s /= double(std::max<std::size_t>(1, d2.size()));
  };
  accumulate(m.predicted, m.predicted_d2, out.predicted);
  accumulate(m.truth, m.truth_d2, out.truth);
  return out;
}

// The same from two meshes: their samples matched, slabs over the truth's samples.
inline ChamferBands chamfer_bands(const io::Mesh& predicted, const io::Mesh& truth, int axis, int bands,
                                  const GeometryOptions& options = {}) {
  if (axis < 0 || axis > 2) throw std::invalid_argument("chamfer_bands: the axis is 0, 1 or 2");
  if (bands < 1) throw std::invalid_argument("chamfer_bands: at least one band");
  const MatchedPoints m = match_samples(predicted, truth, options);
  return chamfer_bands(m, slabs_over(m.truth, axis, bands));
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
