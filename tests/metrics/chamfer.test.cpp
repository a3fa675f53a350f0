// Chamfer / F1 against closed forms: concentric spheres (CD = 2 (r2 - r1)^2
// in the ground truth's unit box, bounded by the tessellation), F1 of 1 and 0
// on either side of the gap, precision against recall with an extra part.
#include "difftrans/metrics/chamfer.hpp"

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;
namespace metrics = difftrans::metrics;
using difftrans::Vec3d;

namespace {

// Smallest distance from the sphere's centre to any point of its triangles,
// over the radius: every vertex lies on the sphere, so a triangle's plane is
// at sqrt(r^2 - R^2) from the centre, R the triangle's circumradius.
double inscribed_ratio(const io::Mesh& m, double r) {
  double lowest = 1.0;
  for (const auto& f : m.triangles) {
    const Vec3d a(m.positions[size_t(f.x)]), b(m.positions[size_t(f.y)]), c(m.positions[size_t(f.z)]);
    const double la = glm::length(b - c), lb = glm::length(c - a), lc = glm::length(a - b);
    const double area = 0.5 * glm::length(glm::cross(b - a, c - a));
    const double circum = la * lb * lc / (4.0 * area);
    lowest = std::min(lowest, std::sqrt(std::max(0.0, 1.0 - (circum / r) * (circum / r))));
  }
  return lowest;
}

io::Mesh merged(const io::Mesh& a, const io::Mesh& b) {
  io::Mesh m = a;
  const int offset = int(a.positions.size());
  m.positions.insert(m.positions.end(), b.positions.begin(), b.positions.end());
  for (const auto& f : b.triangles) m.triangles.push_back(f + offset);
  return m;
}

}  // namespace

TEST_CASE("concentric spheres: CD = 2 (r2 - r1)^2 in the ground truth's unit box, within the tessellation bound") {
  // Ground truth radius 2 about (3, -1, 2): its unit box scales by 1/4 and
  // centres it, so the normalized radii are 0.5 and 0.4.
  const Vec3d centre(3.0, -1.0, 2.0);
  const double r2 = 2.0, r1 = 1.6;
  const io::Mesh gt = uv_sphere(r2, 64, 128, centre);
  const io::Mesh pred = uv_sphere(r1, 64, 128, centre);
  metrics::GeometryOptions options;
  options.samples = 50000;
  const auto m = metrics::evaluate_geometry(pred, gt, options);
  const double rho2 = 0.5, rho1 = 0.4;
  const double h1 = inscribed_ratio(pred, r1), h2 = inscribed_ratio(gt, r2);
  // Every distance is at least the radial gap between the inner sphere's
  // outermost and the outer mesh's innermost point...
  const double lower = 2.0 * (rho2 * h2 - rho1) * (rho2 * h2 - rho1);
  // ... and at most the widest radial gap plus the tangential spacing of the
  // samples: E[s^2] = 1 / (pi lambda) for nearest points of density lambda,
  // scaled by up to rho2 / rho1 between the spheres; allowance 3 E[s^2].
  const double lambda = double(options.samples) / (4.0 * 3.14159265358979 * rho2 * rho2);
  const double upper = 2.0 * (rho2 - rho1 * h1) * (rho2 - rho1 * h1) + 2.0 * 3.0 * (rho2 / rho1) / (3.14159265358979 * lambda);
  CAPTURE(m.chamfer);
  CAPTURE(lower);
  CAPTURE(upper);
  CHECK(m.chamfer >= lower);
  CHECK(m.chamfer <= upper);
  CHECK(m.chamfer == doctest::Approx(2.0 * (rho2 - rho1) * (rho2 - rho1)).epsilon(0.015));
  CHECK(m.f1 == 0.0);  // every distance is near 0.1 > tau
  CHECK(m.samples == 50000);
}

TEST_CASE("F1 on either side of a thin gap: 1 when tau exceeds every distance, 0 below the lower bound") {
  // normalized radii 0.5 and 0.497: gap 0.003
  const io::Mesh gt = uv_sphere(1.0, 64, 128);
  const io::Mesh pred = uv_sphere(0.994, 64, 128);
  const double lowest_gap = 0.5 * inscribed_ratio(gt, 1.0) - 0.497;
  REQUIRE(lowest_gap > 0.002);
  metrics::GeometryOptions options;  // 200,000 samples: nearest samples within ~0.004
  auto m = metrics::evaluate_geometry(pred, gt, options);
  CHECK(m.precision == 1.0);
  CHECK(m.recall == 1.0);
  CHECK(m.f1 == 1.0);
  CHECK(m.chamfer >= 2.0 * lowest_gap * lowest_gap);
  options.tau = 0.002;
  m = metrics::evaluate_geometry(pred, gt, options);
  CHECK(m.precision == 0.0);
  CHECK(m.recall == 0.0);
  CHECK(m.f1 == 0.0);
}

TEST_CASE("precision counts predicted points, recall ground-truth points") {
  // Prediction = the ground-truth sphere plus a far sphere of half the radius:
  // a fifth of its area (so of its samples) is far from the ground truth.
  const io::Mesh gt = uv_sphere(1.0, 32, 64);
  const io::Mesh pred = merged(gt, uv_sphere(0.5, 32, 64, {10.0, 0.0, 0.0}));
  const double far_fraction = io::surface_area(uv_sphere(0.5, 32, 64)) / io::surface_area(pred);
  metrics::GeometryOptions options;
  const auto m = metrics::evaluate_geometry(pred, gt, options);
  CHECK(m.recall == 1.0);  // the ground truth lies inside the prediction
  CHECK(m.precision == doctest::Approx(1.0 - far_fraction).epsilon(0.01));  // binomial sd ~ 0.001
  CHECK(m.f1 == doctest::Approx(2.0 * m.precision / (m.precision + 1.0)));
  const auto swapped = metrics::evaluate_geometry(gt, pred, options);  // now the far part is in the truth
  CHECK(swapped.precision > 0.99);
  CHECK(swapped.recall < 0.9);
}

TEST_CASE("a mesh against itself: CD 0, F1 1; sampling is deterministic for a seed and uniform by area") {
  const io::Mesh cube = cube_mesh();
  const auto m = metrics::evaluate_geometry(cube, cube, {});
  CHECK(m.chamfer == 0.0);
  CHECK(m.f1 == 1.0);
  const auto a = metrics::sample_surface(cube, 60000, 7), b = metrics::sample_surface(cube, 60000, 7);
  const auto c = metrics::sample_surface(cube, 60000, 8);
  CHECK(a == b);
  CHECK(a != c);
  int faces[6] = {0, 0, 0, 0, 0, 0};
  for (const auto& p : a) {
    int on = 0;
    for (int k = 0; k < 3; ++k) {
      REQUIRE(p[k] >= -1e-12);
      REQUIRE(p[k] <= 1.0 + 1e-12);
      if (p[k] < 1e-12) { ++faces[2 * k]; ++on; }
      else if (p[k] > 1.0 - 1e-12) { ++faces[2 * k + 1]; ++on; }
    }
    REQUIRE(on >= 1);  // on the surface
  }
  for (int f : faces) CHECK(std::abs(f - 10000) < 500);  // 1/6 each; binomial sd ~ 91
  CHECK_THROWS_AS(metrics::sample_surface(io::Mesh{}, 10, 1), std::invalid_argument);
}

TEST_CASE("k-d tree nearest neighbours agree with brute force, for any thread count") {
  std::mt19937_64 rng(3);
  std::vector<Vec3d> points(3000), queries(20000);
  for (auto& p : points) p = {metrics::detail::uniform01(rng), metrics::detail::uniform01(rng), metrics::detail::uniform01(rng)};
  for (auto& q : queries) q = {metrics::detail::uniform01(rng) * 1.2 - 0.1, metrics::detail::uniform01(rng), 0.5};
  const auto one = metrics::nearest_squared_distances(queries, points, 1);
  const auto four = metrics::nearest_squared_distances(queries, points, 4);
  CHECK(one == four);
  for (size_t i = 0; i < queries.size(); i += 97) {
    double best = 1e300;
    for (const auto& p : points) best = std::min(best, glm::dot(queries[i] - p, queries[i] - p));
    CHECK(one[i] == doctest::Approx(best).epsilon(1e-12));
  }
  CHECK_THROWS_AS(metrics::nearest_squared_distances(queries, {}), std::invalid_argument);
}

TEST_CASE("vertex distances: the radial gap of concentric spheres, and one displaced vertex stands out") {
  // Normalized radii 0.5 (truth) and 0.4: every vertex of the inner sphere
  // lies 0.1 from the true sphere, less the truth's tessellation, plus the
  // distance to the nearest of the samples (50,000 over an area of pi:
  // a mean near 0.004, the largest of thousands of vertices near 0.013).
  const Vec3d centre(3.0, -1.0, 2.0);
  const io::Mesh gt = uv_sphere(2.0, 64, 128, centre);
  io::Mesh pred = uv_sphere(1.6, 32, 64, centre);
  metrics::GeometryOptions options;
  options.samples = 50000;
  const std::vector<double> d = metrics::vertex_distances(pred, gt, options);
  REQUIRE(d.size() == pred.positions.size());
  const double h2 = inscribed_ratio(gt, 2.0);
  for (double x : d) {
    CHECK(x >= 0.5 * h2 - 0.4 - 1e-9);
    CHECK(x <= 0.1 + 0.01);
  }
  // the predicted mesh equal to the truth but for one vertex pushed out by
  // 0.2 in the truth's units (0.05 normalized)
  io::Mesh same = gt;
  const std::size_t moved = same.positions.size() / 2;
  const difftrans::Vec3f out = glm::normalize(same.positions[moved] - difftrans::Vec3f(centre));
  same.positions[moved] += 0.2f * out;
  const std::vector<double> e = metrics::vertex_distances(same, gt, options);
  double others = 0.0, mean = 0.0;
  for (std::size_t v = 0; v < e.size(); ++v)
    if (v != moved) others = std::max(others, e[v]), mean += e[v] / double(e.size() - 1);
  MESSAGE("on the surface: mean " << mean << ", largest " << others << "; the moved vertex " << e[moved]);
  CHECK(mean < 0.006);
  CHECK(others < 0.02);
  CHECK(e[moved] == doctest::Approx(0.05).epsilon(0.1));
  CHECK(e[moved] > 2.0 * others);
}

TEST_CASE("chamfer bands: a flattened base holds the Chamfer distance in the lowest band; the bands sum to it") {
  // The truth a sphere of radius 2 (normalized 0.5); the prediction the same
  // sphere with every vertex below y = -1.3 (normalized -0.325) lifted to
  // that plane: a cut base, as a visual hull leaves over a concave bottom.
  // Along y in five bands the error lies in the lowest (y < -0.3); along x
  // it is mirror-symmetric.
  const Vec3d centre(3.0, -1.0, 2.0);
  const io::Mesh gt = uv_sphere(2.0, 64, 128, centre);
  io::Mesh cut = gt;
  for (auto& v : cut.positions) v.y = std::max(v.y, float(centre.y - 1.3));
  metrics::GeometryOptions options;
  options.samples = 50000;
  const metrics::GeometryMetrics m = metrics::evaluate_geometry(cut, gt, options);
  const metrics::ChamferBands y = metrics::chamfer_bands(cut, gt, 1, 5, options);
  REQUIRE(y.predicted.size() == 5);
  REQUIRE(y.truth.size() == 5);
  CHECK(y.slabs.from == doctest::Approx(-0.5).epsilon(1e-3));
  CHECK(y.slabs.to == doctest::Approx(0.5).epsilon(1e-3));
  double total = 0.0;
  for (int b = 0; b < 5; ++b) total += y.predicted[std::size_t(b)] + y.truth[std::size_t(b)];
  CHECK(total == doctest::Approx(m.chamfer).epsilon(1e-9));
  const double lowest = y.predicted[0] + y.truth[0];
  MESSAGE("chamfer " << m.chamfer << ", lowest band " << lowest << ", second " << y.predicted[1] + y.truth[1]);
  CHECK(lowest > 0.95 * m.chamfer);
  // where the two coincide (bands 2 to 4) what is left is the samples'
  // spacing: the normalized truth against another sampling of itself, a
  // fifth of its chamfer per band (a sphere's bands have equal areas), twice
  // that allowed
  const io::Mesh unit = uv_sphere(0.5, 64, 128, Vec3d(0.0));
  const double floor = metrics::compare_point_sets(metrics::sample_surface(unit, options.samples, 1),
                                                   metrics::sample_surface(unit, options.samples, 2), options.tau)
                           .chamfer;
  CAPTURE(floor);
  for (int b = 2; b < 5; ++b) CHECK(y.predicted[std::size_t(b)] + y.truth[std::size_t(b)] < 0.4 * floor);
  // the removed cap's points lie on average farther from the plane than the
  // plane's from the cap (mean d^2 0.0102 against 0.0091), and the cap is a
  // larger part of the truth (17.5 %) than the plane of the cut sphere (15 %)
  CHECK(y.truth[0] > y.predicted[0]);
  const metrics::ChamferBands x = metrics::chamfer_bands(cut, gt, 0, 4, options);
  const double left = x.predicted[0] + x.truth[0], right = x.predicted[3] + x.truth[3];
  CHECK(left == doctest::Approx(right).epsilon(0.1));
  CHECK_THROWS_AS(metrics::chamfer_bands(cut, gt, 3, 5, options), std::invalid_argument);
  CHECK_THROWS_AS(metrics::chamfer_bands(cut, gt, 1, 0, options), std::invalid_argument);
}

TEST_CASE("slabs: equal slabs over an extent, outside coordinates clamped; axes by name") {
  const std::vector<Vec3d> points = {Vec3d(0.0, -1.0, 5.0), Vec3d(1.0, 3.0, 5.0), Vec3d(2.0, 1.0, 5.0)};
  const metrics::Slabs s = metrics::slabs_over(points, 1, 4);
  CHECK(s.from == -1.0);
  CHECK(s.to == 3.0);
  CHECK(s.width() == 1.0);
  CHECK(s.lower(2) == 1.0);
  CHECK(s.upper(3) == 3.0);
  CHECK(s.of(-1.0) == 0);
  CHECK(s.of(0.999) == 1);
  CHECK(s.of(1.0) == 2);
  CHECK(s.of(3.0) == 3);    // the top edge belongs to the last slab
  CHECK(s.of(-7.0) == 0);   // below: the first
  CHECK(s.of(42.0) == 3);   // above: the last
  // a flat extent (every point at z = 5): one width, everything in the first slab
  const metrics::Slabs flat = metrics::slabs_over(points, 2, 3);
  CHECK(flat.width() == 1.0);
  CHECK(flat.of(5.0) == 0);
  CHECK_THROWS_AS(metrics::slabs_over(points, 3, 2), std::invalid_argument);
  CHECK_THROWS_AS(metrics::slabs_over(points, 0, 0), std::invalid_argument);
  CHECK(metrics::axis_index("x") == 0);
  CHECK(metrics::axis_index("z") == 2);
  CHECK_THROWS_AS(metrics::axis_index("w"), std::invalid_argument);
  CHECK_THROWS_AS(metrics::axis_index("xy"), std::invalid_argument);
}

TEST_CASE("match_samples: one search serves the metrics and the bands") {
  const io::Mesh gt = uv_sphere(1.0, 32, 64, Vec3d(0.0));
  const io::Mesh pred = uv_sphere(1.05, 32, 64, Vec3d(0.02, 0.0, 0.0));
  metrics::GeometryOptions options;
  options.samples = 20000;
  const metrics::MatchedPoints m = metrics::match_samples(pred, gt, options);
  REQUIRE(m.predicted.size() == m.predicted_d2.size());
  REQUIRE(m.truth.size() == m.truth_d2.size());
  const metrics::GeometryMetrics a = metrics::compare_matched(m, options.tau);
  const metrics::GeometryMetrics b = metrics::evaluate_geometry(pred, gt, options);
  CHECK(a.chamfer == b.chamfer);
  CHECK(a.f1 == b.f1);
  const metrics::ChamferBands bands = metrics::chamfer_bands(m, metrics::slabs_over(m.truth, 0, 3));
  double total = 0.0;
  for (int k = 0; k < 3; ++k) total += bands.predicted[std::size_t(k)] + bands.truth[std::size_t(k)];
  CHECK(total == doctest::Approx(a.chamfer).epsilon(1e-12));
  // 5 % larger and shifted by +0.02 in x: 0.07 apart on the +x side, 0.03 on the −x side
  CHECK(bands.predicted[2] + bands.truth[2] > 2.0 * (bands.predicted[0] + bands.truth[0]));
}
