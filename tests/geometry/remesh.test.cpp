// Isotropic remeshing: closest points on triangles against dense sampling, the
// BVH against brute force, then remeshing spot, a stretched icosphere, a
// stretched box and a torus: edge lengths concentrate around L, the result
// stays a closed 2-manifold of the same genus, stays close to the input both
// ways, and valences move toward 6. And a remeshing whose edges follow the
// curvature (geometry/curvature_sizing.hpp).
#include "difftrans/geometry/remesh.hpp"
#include "difftrans/geometry/curvature_sizing.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "support/shapes.hpp"

using namespace difftrans::geometry;
using glm::vec3;

namespace {

vec3 vertex(const std::vector<float>& p, std::int32_t i) { return vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]); }


// A box of half extents (hx, hy, hz) whose every face is an n × n grid of
// cells, two triangles each: with unequal extents, long thin triangles.
dt_test::Shape sliver_box(float hx, float hy, float hz, int n) {
  dt_test::Shape s;
  std::map<std::tuple<int, int, int>, std::int32_t> ids;  // lattice point -> vertex (welds shared edges)
  const auto id = [&](int i, int j, int k) {
    const auto key = std::make_tuple(i, j, k);
    auto it = ids.find(key);
    if (it == ids.end()) {
      it = ids.emplace(key, std::int32_t(s.positions.size() / 3)).first;
      s.positions.insert(s.positions.end(), {hx * (2.0f * i / n - 1), hy * (2.0f * j / n - 1), hz * (2.0f * k / n - 1)});
    }
    return it->second;
  };
  // face: fixed axis `a` at lattice value `at`, spanned by axes u, v with u × v pointing outward
  const auto add_face = [&](int a, int at, int u, int v) {
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        std::int32_t q[4];
        const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
        for (int c = 0; c < 4; ++c) {
          int l[3];
          l[a] = at;
          l[u] = i + du[c];
          l[v] = j + dv[c];
          q[c] = id(l[0], l[1], l[2]);
        }
        for (int c : {0, 1, 2, 0, 2, 3}) s.triangles.push_back(q[c]);
      }
  };
  add_face(2, 0, 1, 0);  // z = −hz: y × x = −z
  add_face(2, n, 0, 1);
  add_face(1, 0, 0, 2);  // y = −hy: x × z = −y
  add_face(1, n, 2, 0);
  add_face(0, 0, 2, 1);  // x = −hx: z × y = −x
  add_face(0, n, 1, 2);
  return s;
}

// Closed 2-manifold check on flat arrays (each directed edge once, its
// reverse present, one fan per vertex); returns V − E + F or a sentinel.
int closed_manifold_euler(const std::vector<float>& pos, const std::vector<std::int32_t>& tris) {
  constexpr int bad = 1000000;
  std::set<std::pair<int, int>> directed;
  for (std::size_t f = 0; f < tris.size() / 3; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = tris[3 * f + k], b = tris[3 * f + (k + 1) % 3];
      if (a == b || !directed.insert({a, b}).second) return bad;
    }
  for (const auto& [a, b] : directed)
    if (!directed.count({b, a})) return bad;
  const int nv = int(pos.size() / 3);
  std::vector<std::map<int, int>> ring(static_cast<std::size_t>(nv));
  for (std::size_t f = 0; f < tris.size() / 3; ++f)
    for (int k = 0; k < 3; ++k) ring[std::size_t(tris[3 * f + k])][tris[3 * f + (k + 1) % 3]] = tris[3 * f + (k + 2) % 3];
  for (const auto& r : ring) {
    if (r.empty()) return bad;
    const int start = r.begin()->first;
    int w = start;
    std::size_t n = 0;
    do {
      const auto it = r.find(w);
      if (it == r.end()) return bad;
      w = it->second;
      ++n;
    } while (w != start && n <= r.size());
    if (n != r.size()) return bad;
  }
  return nv - int(directed.size() / 2) + int(tris.size() / 3);
}

// Largest (and mean) distance from the points to the triangles, brute force.
double max_distance(const std::vector<float>& points, const std::vector<float>& pos,
                    const std::vector<std::int32_t>& tris, double* mean = nullptr) {
  double worst = 0.0, sum = 0.0;
  for (std::size_t i = 0; i < points.size() / 3; ++i) {
    const vec3 p = vertex(points, std::int32_t(i));
    float best = 1e30f;
    for (std::size_t f = 0; f < tris.size() / 3; ++f) {
      const vec3 q = closest_point_on_triangle(p, vertex(pos, tris[3 * f]), vertex(pos, tris[3 * f + 1]),
                                               vertex(pos, tris[3 * f + 2]));
      best = std::min(best, glm::dot(q - p, q - p));
    }
    worst = std::max(worst, std::sqrt(double(best)));
    sum += std::sqrt(double(best));
  }
  if (mean) *mean = sum / double(points.size() / 3);
  return worst;
}

struct Quality {
  double in_band = 0;       // fraction of edges within [4/5 L, 4/3 L]
  double mean_dev6 = 0;     // mean |valence − 6|
  double valence6 = 0;      // fraction of vertices of valence 6
  int euler = 0;
};

Quality quality(const std::vector<float>& pos, const std::vector<std::int32_t>& tris, float L) {
  Quality q;
  std::set<std::pair<int, int>> edges;
  for (std::size_t f = 0; f < tris.size() / 3; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = tris[3 * f + k], b = tris[3 * f + (k + 1) % 3];
      edges.insert({std::min(a, b), std::max(a, b)});
    }
  std::vector<int> valence(pos.size() / 3, 0);
  int in = 0;
  for (const auto& [a, b] : edges) {
    const float l = glm::length(vertex(pos, a) - vertex(pos, b));
    in += l >= 0.8f * L && l <= 4.0f / 3.0f * L;
    ++valence[std::size_t(a)];
    ++valence[std::size_t(b)];
  }
  q.in_band = double(in) / double(edges.size());
  for (int v : valence) {
    q.mean_dev6 += std::abs(v - 6);
    q.valence6 += v == 6;
  }
  q.mean_dev6 /= double(valence.size());
  q.valence6 /= double(valence.size());
  q.euler = closed_manifold_euler(pos, tris);
  return q;
}

// Remeshes and checks everything the header promises; returns the result.
RemeshResult check_remesh(const dt_test::Shape& in, float L, double max_dist_over_L, const std::string& name,
                          int iterations = 10) {
  INFO(name);
  const Quality before = quality(in.positions, in.triangles, L);
  REQUIRE(before.euler < 1000000);
  RemeshOptions o;
  o.target_length = L;
  o.iterations = iterations;
  const RemeshResult r = remesh(in.positions, in.triangles, o);
  REQUIRE(r.report.ok());
  const Quality after = quality(r.positions, r.triangles, L);
  const double out_to_in = max_distance(r.positions, in.positions, in.triangles);
  // from the input's vertices (its creases and tips) and its triangles' centroids
  std::vector<float> centroids;
  for (std::size_t f = 0; f < in.triangles.size() / 3; ++f) {
    const vec3 c = (vertex(in.positions, in.triangles[3 * f]) + vertex(in.positions, in.triangles[3 * f + 1]) +
                    vertex(in.positions, in.triangles[3 * f + 2])) / 3.0f;
    centroids.insert(centroids.end(), {c.x, c.y, c.z});
  }
  double mean_in_to_out = 0.0;
  const double in_to_out = std::max(max_distance(in.positions, r.positions, r.triangles),
                                    max_distance(centroids, r.positions, r.triangles, &mean_in_to_out));
  MESSAGE(name << ": " << in.triangles.size() / 3 << " -> " << r.triangles.size() / 3 << " triangles; in band "
               << before.in_band << " -> " << after.in_band << "; mean |valence - 6| " << before.mean_dev6 << " -> "
               << after.mean_dev6 << "; valence 6 " << before.valence6 << " -> " << after.valence6
               << "; distance out->in " << out_to_in / L << " L, in->out max " << in_to_out / L << " L, mean "
               << mean_in_to_out / L << " L; splits "
               << r.stats.splits << " collapses " << r.stats.collapses << " flips " << r.stats.flips);
  CHECK(after.euler == before.euler);  // closed 2-manifold, same genus
  CHECK(after.in_band > 0.9);
  // valences end near 6 (an input already regular everywhere cannot improve)
  CHECK(after.mean_dev6 < 0.3);
  if (before.mean_dev6 > 0.2) CHECK(after.mean_dev6 < before.mean_dev6);  // spot: 0.24 before
  CHECK(after.valence6 > 0.7);
  CHECK(out_to_in < 0.01 * L);  // vertices are projected onto the input
  // the input lies near the result: the largest gap is the chord error at
  // the sharpest features (tips, creases), the mean over the input's
  // triangles far below it
  CHECK(in_to_out < max_dist_over_L * L);
  CHECK(mean_in_to_out < 0.075 * L);
  return r;
}

}  // namespace

TEST_CASE("closest point on a triangle against dense sampling") {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int trial = 0; trial < 200; ++trial) {
    const vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c = trial % 10 == 0 ? a + 0.5f * (b - a) + vec3(1e-3f, 0, 0) : vec3(u(rng), u(rng), u(rng));
    const vec3 p = 2.0f * vec3(u(rng), u(rng), u(rng));
    const vec3 q = closest_point_on_triangle(p, a, b, c);
    // q lies on the triangle: its barycentrics are in [0, 1]
    const vec3 n = glm::cross(b - a, c - a);
    const float n2 = glm::dot(n, n);
    const float beta = glm::dot(glm::cross(q - a, c - a), n) / n2, gamma = glm::dot(glm::cross(b - a, q - a), n) / n2;
    CHECK(std::abs(glm::dot(q - a, n)) < 1e-4f * std::sqrt(n2));
    CHECK(beta >= -1e-3f);
    CHECK(gamma >= -1e-3f);
    CHECK(beta + gamma <= 1.0f + 1e-3f);
    // no sample of the triangle is closer
    const float dq = glm::length(p - q);
    float best = 1e30f;
    const int k = 60;
    for (int i = 0; i <= k; ++i)
      for (int j = 0; i + j <= k; ++j) {
        const vec3 s = a + (b - a) * (float(i) / k) + (c - a) * (float(j) / k);
        best = std::min(best, glm::length(p - s));
      }
    CHECK(dq <= best + 1e-5f);
    CHECK(dq >= best - 0.03f * glm::length(b - a) - 0.03f * glm::length(c - a));  // the sampling's resolution
  }
}

TEST_CASE("ClosestPointTree agrees with brute force") {
  const dt_test::Shape spot = dt_test::load_normalized_mesh(DIFFTRANS_DATA_DIR "/meshes/spot.obj");
  const ClosestPointTree tree(spot.positions, spot.triangles);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-0.8f, 0.8f);
  for (int trial = 0; trial < 150; ++trial) {
    const vec3 p(u(rng), u(rng), u(rng));
    const ClosestPointTree::Result r = tree.closest(p);
    float best = 1e30f;
    for (std::size_t f = 0; f < spot.triangles.size() / 3; ++f) {
      const vec3 q = closest_point_on_triangle(p, vertex(spot.positions, spot.triangles[3 * f]),
                                               vertex(spot.positions, spot.triangles[3 * f + 1]),
                                               vertex(spot.positions, spot.triangles[3 * f + 2]));
      best = std::min(best, glm::dot(q - p, q - p));
    }
    CHECK(r.triangle >= 0);
    CHECK(r.distance2 == doctest::Approx(best).epsilon(1e-5));
    CHECK(glm::dot(r.point - p, r.point - p) == doctest::Approx(r.distance2).epsilon(1e-5));
  }
}

TEST_CASE("remeshing spot") {
  const dt_test::Shape spot = dt_test::load_normalized_mesh(DIFFTRANS_DATA_DIR "/meshes/spot.obj");
  check_remesh(spot, 0.02f, 0.6, "spot, L = 0.02");
  check_remesh(spot, 0.04f, 0.75, "spot, L = 0.04");
}

TEST_CASE("remeshing badly shaped meshes") {
  // a stretched icosphere: long thin triangles along x
  dt_test::Shape ico = dt_test::make_icosphere(1.0f, 3);
  for (std::size_t i = 0; i < ico.positions.size(); i += 3) ico.positions[i] *= 4.0f;
  check_remesh(ico, 0.15f, 0.2, "stretched icosphere");
  // a box of slivers (cells 8 : 1): its sharp edges and corners get cut a
  // little (no feature lines)
  const dt_test::Shape box = sliver_box(2.0f, 0.25f, 0.4f, 8);
  REQUIRE(closed_manifold_euler(box.positions, box.triangles) == 2);
  check_remesh(box, 0.1f, 1.0, "sliver box");
}

TEST_CASE("remeshing a torus keeps genus 1") {
  const dt_test::Shape t = dt_test::make_torus(48, 6, 1.0f, 0.3f);  // coarse around the tube, fine around the ring
  const RemeshResult r = check_remesh(t, 0.08f, 0.4, "torus");
  CHECK(closed_manifold_euler(r.positions, r.triangles) == 0);
}

TEST_CASE("the building blocks one at a time") {
  HalfEdgeMesh m = HalfEdgeMesh::from_triangles(dt_test::make_icosphere(1.0f, 2).positions,
                                                dt_test::make_icosphere(1.0f, 2).triangles);
  const float L0 = mean_edge_length(m);
  // splitting at 4/3 of half the length leaves no edge longer than that
  const int splits = split_long_edges(m, 0.5f * L0);
  CHECK(splits > 0);
  for (int e = 0; e < m.num_edges(); ++e)
    if (!m.edge_deleted(e)) CHECK(m.edge_length(e) <= 0.5f * L0);
  CHECK(m.validate() == "");
  // collapsing everything below 0.8 L0 with high = 4/3 L0
  const int collapses = collapse_short_edges(m, 0.8f * L0, 4.0f / 3.0f * L0);
  CHECK(collapses > 0);
  CHECK(m.validate() == "");
  CHECK(m.euler_characteristic() == 2);
  for (int e = 0; e < m.num_edges(); ++e)
    if (!m.edge_deleted(e)) CHECK(m.edge_length(e) <= 4.0f / 3.0f * L0 + 1e-6f);
  // flips never increase the total valence deviation
  const auto deviation = [&] {
    int d = 0;
    for (int v = 0; v < m.num_vertices(); ++v)
      if (!m.vertex_deleted(v)) d += std::abs(m.valence(v) - 6);
    return d;
  };
  const int d0 = deviation();
  const int flips = equalize_valences(m);
  CHECK(flips > 0);
  CHECK(deviation() < d0);
  CHECK(m.validate() == "");
  // relaxation moves vertices within their tangent planes: on the unit sphere
  // their radius changes only to second order; projection puts them back
  tangential_relaxation(m);
  double worst = 0.0;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (!m.vertex_deleted(v)) worst = std::max(worst, std::abs(double(glm::length(m.position(v))) - 1.0));
  CHECK(worst < 0.05);
  const dt_test::Shape fine = dt_test::make_icosphere(1.0f, 4);
  const ClosestPointTree sphere(fine.positions, fine.triangles);
  project_to_surface(m, sphere);
  for (int v = 0; v < m.num_vertices(); ++v)
    if (!m.vertex_deleted(v)) CHECK(glm::length(m.position(v)) == doctest::Approx(1.0).epsilon(2e-3));
}

namespace {

// Two shapes as one mesh: b's vertices shifted by `offset`.
dt_test::Shape joined(const dt_test::Shape& a, const dt_test::Shape& b, const vec3& offset) {
  dt_test::Shape s = a;
  const std::int32_t base = std::int32_t(a.positions.size() / 3);
  for (std::size_t i = 0; i < b.positions.size(); i += 3)
    s.positions.insert(s.positions.end(), {b.positions[i] + offset.x, b.positions[i + 1] + offset.y,
                                           b.positions[i + 2] + offset.z});
  for (std::int32_t t : b.triangles) s.triangles.push_back(t + base);
  return s;
}


}  // namespace

TEST_CASE("curvature-adaptive remeshing: long edges where flat, short where curved, and it ends") {
  // a sphere of radius 1 beside one of radius 0.1: with a chord tolerance of
  // 0.002 the large one asks for edges of 0.11 (clamped to 0.08), the small
  // one for 0.035 (clamped up to 0.04)
  const dt_test::Shape s = joined(dt_test::make_icosphere(1.0f, 4), dt_test::make_icosphere(0.1f, 4), vec3(3, 0, 0));
  CurvatureSizing cs;
  cs.min_length = 0.04f;
  cs.max_length = 0.08f;
  cs.tolerance = 0.002f;
  const CurvatureSizingResult sizing = curvature_sizing(s.positions, s.triangles, cs);
  RemeshOptions o;
  o.target_length = cs.min_length;
  o.iterations = 10;
  o.sizing = &sizing.length;
  const RemeshResult r = remesh(s.positions, s.triangles, o);
  REQUIRE(r.report.ok());
  CHECK(closed_manifold_euler(r.positions, r.triangles) == 4);  // two spheres
  double big = 0.0, small = 0.0;
  int nb = 0, ns = 0;
  for (std::size_t f = 0; f < r.triangles.size() / 3; ++f)
    for (int k = 0; k < 3; ++k) {
      const vec3 a = vertex(r.positions, r.triangles[3 * f + std::size_t(k)]);
      const vec3 b = vertex(r.positions, r.triangles[3 * f + std::size_t(k + 1) % 3]);
      if (a.x > 2.0f) {
        small += glm::length(a - b);
        ++ns;
      } else {
        big += glm::length(a - b);
        ++nb;
      }
    }
  big /= nb;
  small /= ns;
  MESSAGE("mean edge: large sphere " << big << ", small sphere " << small << "; " << r.positions.size() / 3
                                     << " vertices, splits " << r.stats.splits << ", collapses " << r.stats.collapses);
  CHECK(big == doctest::Approx(0.08).epsilon(0.15));
  CHECK(small == doctest::Approx(0.04).epsilon(0.15));
  // the vertices stay on the input
  CHECK(max_distance(r.positions, s.positions, s.triangles) < 1e-3);
  // a uniform sizing remeshes as the uniform target does (its splits come one
  // per edge and pass, so not vertex for vertex): as many vertices within 10 %
  std::vector<float> same(s.positions.size() / 3, 0.06f);
  RemeshOptions u;
  u.target_length = 0.06f;
  u.iterations = 3;
  const RemeshResult plain = remesh(s.positions, s.triangles, u);
  u.sizing = &same;
  const RemeshResult sized = remesh(s.positions, s.triangles, u);
  CHECK(sized.positions.size() == doctest::Approx(double(plain.positions.size())).epsilon(0.1));
}
