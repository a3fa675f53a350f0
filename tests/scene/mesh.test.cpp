// Triangle mesh: vertex normals (cube, sphere) against an independent
// computation, the CSR adjacency, Möller–Trumbore in S (interior, edge,
// vertex, degenerate), and derivatives of hit point, barycentrics and shading
// normal with respect to vertex coordinates and the ray against central
// differences; forward against reverse through the library's readers;
// the triangle records against the arrays they are made from.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>

#include "scene/scene_check.hpp"

using namespace dt_test;
using scene::MeshView;
using scene::NormalMode;
using scene::TriangleMesh;

namespace {

TriangleMesh cube() {
  std::vector<float> p;
  for (int k = 0; k < 8; ++k) {
    p.push_back(k & 1 ? 0.5f : -0.5f);
    p.push_back(k & 2 ? 0.5f : -0.5f);
    p.push_back(k & 4 ? 0.5f : -0.5f);
  }
  // two counter-clockwise (seen from outside) triangles per face
  std::vector<std::int32_t> t = {0, 2, 3, 0, 3, 1,  4, 5, 7, 4, 7, 6,  0, 1, 5, 0, 5, 4,
                                 2, 6, 7, 2, 7, 3,  0, 4, 6, 0, 6, 2,  1, 3, 7, 1, 7, 5};
  return TriangleMesh(p, t);
}

// Icosahedron subdivided once (42 vertices, 80 faces) on the unit sphere.
TriangleMesh icosphere() {
  const double g = (1 + std::sqrt(5.0)) / 2;
  std::vector<Vec3d> v = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                          {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  for (Vec3d& x : v) x = glm::normalize(x);
  std::vector<std::int32_t> f = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4, 11, 10, 2,
                                 10, 7, 6, 7, 1, 8, 3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8, 3, 8, 9, 4, 9, 5,
                                 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1};
  std::map<std::pair<int, int>, int> mid;
  const auto midpoint = [&](int a, int b) {
    const auto key = std::make_pair(std::min(a, b), std::max(a, b));
    const auto it = mid.find(key);
    if (it != mid.end()) return it->second;
    v.push_back(glm::normalize(v[std::size_t(a)] + v[std::size_t(b)]));
    return mid[key] = int(v.size()) - 1;
  };
  std::vector<std::int32_t> f2;
  for (std::size_t k = 0; k < f.size(); k += 3) {
    const int a = f[k], b = f[k + 1], c = f[k + 2];
    const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
    for (int x : {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca}) f2.push_back(x);
  }
  std::vector<float> p;
  for (const Vec3d& x : v)
    for (int c = 0; c < 3; ++c) p.push_back(float(x[c]));
  return TriangleMesh(p, f2);
}

// Independent reference: per-vertex sum of unit face normals, normalized.
std::vector<Vec3d> reference_normals(const std::vector<double>& pos, const std::vector<std::int32_t>& tris) {
  std::vector<Vec3d> n(pos.size() / 3, Vec3d(0.0));
  const auto P = [&](std::int32_t i) { return Vec3d(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]); };
  for (std::size_t f = 0; f < tris.size(); f += 3) {
    const Vec3d c = glm::cross(P(tris[f + 1]) - P(tris[f]), P(tris[f + 2]) - P(tris[f]));
    if (glm::length(c) == 0.0) continue;
    for (int k = 0; k < 3; ++k) n[std::size_t(tris[f + k])] += glm::normalize(c);
  }
  for (Vec3d& x : n) x = glm::normalize(x);
  return n;
}

std::vector<double> to_double(const std::vector<float>& v) { return std::vector<double>(v.begin(), v.end()); }

// A view whose positions are buffer 0 of an OverrideReader.
MeshView param_view(const TriangleMesh& m) { return m.view(0); }

}  // namespace

TEST_CASE("adjacency: every face once around each of its vertices") {
  const TriangleMesh c = cube();
  CHECK(c.vf_offsets.size() == 9);
  CHECK(c.vf_offsets.back() == 36);
  for (std::int32_t v = 0; v < 8; ++v)
    for (std::int32_t k = c.vf_offsets[std::size_t(v)]; k < c.vf_offsets[std::size_t(v) + 1]; ++k) {
      const std::int32_t f = c.vf_faces[std::size_t(k)];
      const bool has = c.triangles[std::size_t(3 * f)] == v || c.triangles[std::size_t(3 * f + 1)] == v ||
                       c.triangles[std::size_t(3 * f + 2)] == v;
      CHECK(has);
    }
  // a face naming a vertex twice is listed once for it
  const TriangleMesh d({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2, 0, 0, 1});
  CHECK(d.vf_offsets == std::vector<std::int32_t>{0, 2, 4, 5});
}

TEST_CASE("vertex normals: mean of unit face normals (cube, sphere)") {
  for (const TriangleMesh& m : {cube(), icosphere()}) {
    const std::vector<double> pos = to_double(m.positions);
    const std::vector<Vec3d> ref = reference_normals(pos, m.triangles);
    const std::vector<std::vector<double>> values{pos};
    OverrideReader<double> r{&values};
    const MeshView view = param_view(m);
    for (std::int32_t v = 0; v < m.num_vertices(); ++v) {
      CAPTURE(v);
      const Vec3d nf(m.vertex_normals[std::size_t(3 * v)], m.vertex_normals[std::size_t(3 * v + 1)],
                     m.vertex_normals[std::size_t(3 * v + 2)]);
      CHECK(glm::length(nf - ref[std::size_t(v)]) < 1e-6);
      const Vec3d nd = scene::vertex_normal<double>(r, view, v);
      CHECK(glm::length(nd - ref[std::size_t(v)]) < 1e-12);
      // the normal points away from the centre
      const Vec3d p(pos[std::size_t(3 * v)], pos[std::size_t(3 * v + 1)], pos[std::size_t(3 * v + 2)]);
      CHECK(glm::dot(nd, glm::normalize(p)) > (m.num_vertices() == 8 ? 0.5 : 0.99));
    }
  }
  // the icosahedron's own 12 vertices: five-fold symmetric, so exactly radial
  const TriangleMesh s = icosphere();
  for (std::int32_t v = 0; v < 12; ++v) {
    const Vec3d p(s.positions[std::size_t(3 * v)], s.positions[std::size_t(3 * v + 1)], s.positions[std::size_t(3 * v + 2)]);
    const Vec3d n(s.vertex_normals[std::size_t(3 * v)], s.vertex_normals[std::size_t(3 * v + 1)],
                  s.vertex_normals[std::size_t(3 * v + 2)]);
    CHECK(glm::length(n - glm::normalize(p)) < 1e-6);
  }
  // a cube corner touching two triangles of one face and one of each other face
  const TriangleMesh c = cube();
  const Vec3d n0(c.vertex_normals[0], c.vertex_normals[1], c.vertex_normals[2]);
  CHECK(n0.x < 0);
  CHECK(n0.y < 0);
  CHECK(n0.z < 0);
}

TEST_CASE_TEMPLATE("Möller–Trumbore: interior, edge and vertex hits", S, DT_ALL_SCALARS) {
  const auto V = [](double x, double y, double z) { return Vec3<S>(S(x), S(y), S(z)); };
  const Vec3<S> p0 = V(0, 0, 0), p1 = V(2, 0, 0), p2 = V(0, 1, 0);
  const double eps = tol<S>();
  struct Case {
    Vec3d o, d;
    double t, b1, b2;
  };
  const Case cases[] = {
      {{0.5, 0.25, 2}, {0, 0, -1}, 2, 0.25, 0.25},      // interior
      {{1.0, 0.5, -1}, {0, 0, 2}, 0.5, 0.5, 0.5},       // on the edge p1 p2, from below
      {{0.8, 0, 1}, {0, 0, -1}, 1, 0.4, 0.0},           // on the edge p0 p1
      {{2, 0, 3}, {0, 0, -1}, 3, 1.0, 0.0},             // at vertex p1
      {{0, 0, 1}, {0, 0, -0.5}, 2, 0.0, 0.0},           // at vertex p0
      {{-1, 0.5, 1}, {1, 0, -1}, 1, 0.0, 0.5},          // oblique, on the edge p0 p2
      {{3, 3, 1}, {0, 0, -1}, 1, 1.5, 3.0},             // the plane, outside the triangle
  };
  for (const Case& c : cases) {
    CAPTURE(c.o);
    const scene::TriangleHit<S> h = scene::intersect_triangle(V(c.o.x, c.o.y, c.o.z), V(c.d.x, c.d.y, c.d.z), p0, p1, p2);
    CHECK(h.valid);
    CHECK(close(double(ad::value_of(h.t)), c.t, eps));
    CHECK(close(double(ad::value_of(h.b1)), c.b1, eps));
    CHECK(close(double(ad::value_of(h.b2)), c.b2, eps));
    CHECK(h.inside == (c.b1 <= 1 && c.b2 <= 1 && c.b1 + c.b2 <= 1 + 1e-12));
  }
}

TEST_CASE_TEMPLATE("degenerate triangles and parallel rays are invalid, never NaN", S, DT_ALL_SCALARS) {
  const auto V = [](double x, double y, double z) { return Vec3<S>(S(x), S(y), S(z)); };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    Vec3d p0, p1, p2, o, d;
  };
  const Case cases[] = {
      {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0.5, 0.1, 1}, {0, 0, -1}},        // collinear
      {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}, {1, 1, 2}, {0, 0, -1}},            // a point
      {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0.2, 0}, {1, 0, 0}},          // ray in the plane
      {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.2, 0.2, 1}, {0, 0, 0}},         // zero direction
      {{0, 0, 0}, {1, nan, 0}, {0, 1, 0}, {0.2, 0.2, 1}, {0, 0, -1}},      // NaN vertex
      {{0, 0, 0}, {1e-30, 0, 0}, {0, 1e-30, 0}, {0, 0, 1}, {0, 0, -1}},    // vanishing area (float: 0)
  };
  for (const Case& c : cases) {
    CAPTURE(c.p1);
    const scene::TriangleHit<S> h =
        scene::intersect_triangle(V(c.o.x, c.o.y, c.o.z), V(c.d.x, c.d.y, c.d.z), V(c.p0.x, c.p0.y, c.p0.z),
                                  V(c.p1.x, c.p1.y, c.p1.z), V(c.p2.x, c.p2.y, c.p2.z));
    if (c.p1.x == 1e-30 && std::is_same_v<ad::scalar_t<S>, double>) {
      CHECK(h.valid);  // tiny but well-shaped: fine in double
      continue;
    }
    CHECK_FALSE(h.valid);
    CHECK_FALSE(h.inside);
    CHECK(all_finite(h.t));
    CHECK(all_finite(h.b1));
    CHECK(all_finite(h.b2));
  }
  // a zero-area triangle of a mesh: invalid surface point, finite normals
  const TriangleMesh m({0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0}, {0, 1, 2, 0, 1, 3});
  const std::vector<std::vector<double>> values{to_double(m.positions)};
  OverrideReader<S> r{&values};
  const scene::SurfaceHit<S> sh =
      scene::reevaluate_hit(r, param_view(m), 0, V(0.5, 0.0, 1.0), V(0.0, 0.0, -1.0), NormalMode::one_ring);
  CHECK_FALSE(sh.hit.valid);
  CHECK_FALSE(sh.point.valid);
  CHECK(all_finite(sh.point.p));
  CHECK(all_finite(sh.point.n));
  CHECK(all_finite(sh.point.ng));
}

TEST_CASE_TEMPLATE("degenerate hits have finite derivatives", S, DT_AD_SCALARS) {
  for (int comp = 0; comp < 9; ++comp) {
    const auto f = [&](auto x) {
      using R = decltype(x);
      Vec3<R> p[3] = {Vec3<R>(R(0), R(0), R(0)), Vec3<R>(R(1), R(0), R(0)), Vec3<R>(R(2), R(0), R(0))};
      p[comp / 3][comp % 3] = x;
      const auto h = scene::intersect_triangle(Vec3<R>(R(0.5), R(0.1), R(1)), Vec3<R>(R(0), R(0), R(-1)), p[0], p[1], p[2]);
      return h.t + h.b1 + h.b2;
    };
    const double x0 = comp / 3 == 1 && comp % 3 == 0 ? 1.0 : (comp / 3 == 2 && comp % 3 == 0 ? 2.0 : 0.0);
    CHECK(std::isfinite(derivative<S>(f, x0)));
  }
}

TEST_CASE_TEMPLATE("hit point and shading normal: derivatives with respect to vertex coordinates", S, DT_AD_SCALARS) {
  const TriangleMesh m = icosphere();
  const std::vector<std::vector<double>> values{to_double(m.positions)};
  const MeshView view = param_view(m);
  const std::int32_t tri = 17;
  const std::int32_t* idx = m.triangles.data() + 3 * tri;
  // the vertices whose coordinates the shading normal depends on: the one-rings
  std::vector<bool> ring(std::size_t(m.num_vertices()), false);
  for (int k = 0; k < 3; ++k)
    for (std::int32_t j = m.vf_offsets[std::size_t(idx[k])]; j < m.vf_offsets[std::size_t(idx[k]) + 1]; ++j)
      for (int c = 0; c < 3; ++c) ring[std::size_t(m.triangles[std::size_t(3 * m.vf_faces[std::size_t(j)] + c)])] = true;
  for (const auto& [b1, b2] : {std::pair<double, double>{0.3, 0.25}, {0.0, 0.5} /* edge */, {1.0, 0.0} /* vertex */}) {
    int ring_n = 0, ring_other = 0;  // non-zero derivatives from ring vertices beyond the triangle
    for (int out = 0; out < 9; ++out) {
      const auto f = [&](auto& r) {
        using R = decltype(r.x);
        const scene::SurfacePoint<R> sp = scene::surface_point(r, view, tri, R(b1), R(b2), NormalMode::one_ring);
        return out < 3 ? sp.p[out] : (out < 6 ? sp.n[out - 3] : sp.ng[out - 6]);
      };
      for (std::int32_t i = 0; i < 3 * m.num_vertices(); ++i) {
        CAPTURE(b1);
        CAPTURE(out);
        CAPTURE(i);
        const double d = param_derivative<S>(values, 0, i, f);
        const double fd = param_difference(values, 0, i, f);
        CHECK(std::abs(d - fd) <= tol<S>() * 10 * std::max(1.0, std::abs(fd)));
        const std::int32_t v = i / 3;
        const bool own = v == idx[0] || v == idx[1] || v == idx[2];
        if (!ring[std::size_t(v)]) CHECK(d == 0.0);
        if (ring[std::size_t(v)] && !own && d != 0.0) ++(out >= 3 && out < 6 ? ring_n : ring_other);
      }
    }
    // the shading normal reaches the one-ring beyond the triangle; the point
    // and the geometric normal do not
    CAPTURE(b1);
    CHECK(ring_n > 0);
    CHECK(ring_other == 0);
  }
}

TEST_CASE_TEMPLATE("re-evaluated hit: derivatives with respect to vertices and the ray", S, DT_AD_SCALARS) {
  const TriangleMesh m = icosphere();
  const std::vector<std::vector<double>> values{to_double(m.positions)};
  const MeshView view = param_view(m);
  const std::int32_t tri = 33;
  const std::int32_t* idx = m.triangles.data() + 3 * tri;
  const auto P = [&](std::int32_t i) { return Vec3d(values[0][std::size_t(3 * i)], values[0][std::size_t(3 * i + 1)], values[0][std::size_t(3 * i + 2)]); };
  // rays towards an interior point, an edge midpoint and a vertex, from outside
  const Vec3d targets[] = {0.2 * P(idx[0]) + 0.5 * P(idx[1]) + 0.3 * P(idx[2]), 0.5 * (P(idx[1]) + P(idx[2])), P(idx[0])};
  for (const Vec3d& target : targets) {
    const Vec3d o = 2.5 * glm::normalize(target + Vec3d(0.1, -0.05, 0.08));
    const Vec3d d = glm::normalize(target - o);
    for (int out = 0; out < 9; ++out) {
      const auto eval = [&](auto& r, const auto& ro, const auto& rd) {
        using R = std::decay_t<decltype(ro.x)>;
        const scene::SurfaceHit<R> h = scene::reevaluate_hit(r, view, tri, ro, rd, NormalMode::one_ring);
        REQUIRE(h.hit.valid);
        return out == 0 ? h.hit.t : out == 1 ? h.hit.b1 : out == 2 ? h.hit.b2 : out < 6 ? h.point.p[out - 3] : h.point.n[out - 6];
      };
      // vertex coordinates of the triangle and of one ring neighbour
      for (std::int32_t i : {3 * idx[0], 3 * idx[1] + 1, 3 * idx[2] + 2, 3 * idx[0] + 1,
                             3 * m.triangles[std::size_t(3 * m.vf_faces[std::size_t(m.vf_offsets[std::size_t(idx[1])])] + 0)]}) {
        const auto f = [&](auto& r) {
          using R = decltype(r.x);
          return eval(r, Vec3<R>(R(o.x), R(o.y), R(o.z)), Vec3<R>(R(d.x), R(d.y), R(d.z)));
        };
        CAPTURE(target);
        CAPTURE(out);
        CAPTURE(i);
        const double ad_d = param_derivative<S>(values, 0, i, f);
        const double fd = param_difference(values, 0, i, f);
        CHECK(std::abs(ad_d - fd) <= tol<S>() * 10 * std::max(1.0, std::abs(fd)));
      }
      // ray origin and direction
      for (int comp = 0; comp < 6; ++comp) {
        const auto g = [&](auto x) {
          using R = decltype(x);
          OverrideReader<R> r{&values};
          Vec3<R> ro(R(o.x), R(o.y), R(o.z)), rd(R(d.x), R(d.y), R(d.z));
          (comp < 3 ? ro : rd)[comp % 3] = x;
          return eval(r, ro, rd);
        };
        CAPTURE(comp);
        const double x0 = (comp < 3 ? o : d)[comp % 3];
        const double ad_d = derivative<S>(g, x0);
        const double fd = central_difference(g, x0);
        CHECK(std::abs(ad_d - fd) <= tol<S>() * 10 * std::max(1.0, std::abs(fd)));
      }
    }
  }
}

TEST_CASE("normal modes: precomputed and one-ring agree; frozen positions cost no leaves") {
  const TriangleMesh m = icosphere();
  ad::ParamSet set;
  set.buffers[0].values = m.positions.data();
  set.buffers[0].size = std::int32_t(m.positions.size());
  ad::ParamReader<float> plain(&set);
  for (std::int32_t tri : {0, 17, 79}) {
    const auto a = scene::surface_point(plain, m.view(0), tri, 0.2f, 0.3f, NormalMode::precomputed);
    const auto b = scene::surface_point(plain, m.view(0), tri, 0.2f, 0.3f, NormalMode::one_ring);
    CHECK(glm::length(a.n - b.n) < 1e-6f);
    CHECK(a.p == b.p);
  }
  ad::Tape<float> tape(1 << 14);
  std::vector<ad::LeafRecord> log(1024);
  ad::ParamReader<ad::Var<float>> rev(&set, &tape, log.data(), 1024);
  using V = ad::Var<float>;
  const V b1 = tape.variable(0.2f), b2 = tape.variable(0.3f);
  const auto frozen = scene::surface_point(rev, m.view(), 17, b1, b2);  // positions buffer -1: constants
  CHECK(rev.size() == 0);
  tape.backward(frozen.p.x);
  CHECK(tape.adjoint(b1) != 0.0f);  // still differentiable in the barycentrics
  const auto live = scene::surface_point(rev, m.view(0), 17, b1, b2);  // automatic: the one-rings
  // each vertex of the union of the three one-rings read once (cache), 3 coordinates each
  std::vector<bool> seen(std::size_t(m.num_vertices()), false);
  int unique = 0;
  for (int k = 0; k < 3; ++k) {
    const std::int32_t v = m.triangles[std::size_t(3 * 17 + k)];
    for (std::int32_t j = m.vf_offsets[std::size_t(v)]; j < m.vf_offsets[std::size_t(v) + 1]; ++j)
      for (int c = 0; c < 3; ++c) {
        const std::int32_t u = m.triangles[std::size_t(3 * m.vf_faces[std::size_t(j)] + c)];
        if (!seen[std::size_t(u)]) ++unique;
        seen[std::size_t(u)] = true;
      }
  }
  CHECK(rev.size() == 3 * unique);
  CHECK(glm::length(ad::value_of(live.n) - ad::value_of(frozen.n)) < 1e-6f);
}

TEST_CASE("forward and reverse mode agree through the library's readers") {
  const TriangleMesh m = icosphere();
  const MeshView view = m.view(3);
  for (int out = 0; out < 9; ++out) {
    check_forward_vs_reverse(m.positions, 3, [&](auto& reader) {
      using R = std::decay_t<decltype(reader.read(0, 0))>;
      const Vec3<R> o(R(0.1), R(0.2), R(3.0)), d(R(-0.02), R(-0.05), R(-1.0));
      const scene::SurfaceHit<R> h = scene::reevaluate_hit(reader, view, 21, o, d, NormalMode::one_ring);
      return out == 0 ? h.hit.t : out == 1 ? h.hit.b1 : out == 2 ? h.hit.b2 : out < 6 ? h.point.p[out - 3] : h.point.n[out - 6];
    });
  }
}

namespace {

// The bits of a float, so that two values compare equal only when they are
// the same number (and NaN equals NaN).
std::uint32_t bits(float x) {
  std::uint32_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

template <class S>
void check_same_bits(const S& a, const S& b) {
  CHECK(bits(float(ad::value_of(a))) == bits(float(ad::value_of(b))));
  // derivatives: equal numbers (a constant's zero derivative may carry
  // either sign: the records hold the face normal as a constant)
  if constexpr (ad::is_dual_v<S>)
    for (int k = 0; k < S::lanes; ++k)
      CHECK((a.grad[k] == b.grad[k] || (std::isnan(a.grad[k]) && std::isnan(b.grad[k]))));
}

template <class S>
void check_same_bits(const Vec3<S>& a, const Vec3<S>& b) {
  for (int c = 0; c < 3; ++c) check_same_bits(a[c], b[c]);
}

}  // namespace

TEST_CASE_TEMPLATE("triangle records: the hits and surface points of the arrays, bit for bit", S, float,
                   ad::Dual<float, 1>, ad::Dual<float, 3>) {
  TriangleMesh m = icosphere();
  m.triangles.insert(m.triangles.end(), {0, 1, 1});  // a face of zero area: its record has none
  m.build_adjacency();
  // moved as an optimizer step moves them; update_normals remakes the records
  for (std::size_t k = 0; k < m.positions.size(); ++k) m.positions[k] *= 1.0f + 0.07f * std::sin(float(k));
  m.update_normals();
  const MeshView with = m.view();
  REQUIRE(with.records != nullptr);
  MeshView without = with;
  without.records = nullptr;
  CHECK(scene::detail::use_records<S>(with, NormalMode::automatic));
  CHECK(scene::detail::use_records<S>(with, NormalMode::precomputed));
  CHECK_FALSE(scene::detail::use_records<S>(with, NormalMode::one_ring));     // normals from the one-rings
  CHECK_FALSE(scene::detail::use_records<S>(m.view(0), NormalMode::automatic));  // the positions a parameter
  CHECK_FALSE(scene::detail::use_records<double>(with, NormalMode::automatic));  // made in float
  CHECK_FALSE(scene::detail::use_records<S>(without, NormalMode::automatic));
  CHECK(m.records.back().area == 0);

  ad::ParamReader<float> unused(nullptr);  // frozen positions: nothing is read through it
  int hits = 0;
  for (std::int32_t f = 0; f < m.num_triangles(); ++f) {
    CAPTURE(f);
    const std::int32_t* t = &m.triangles[std::size_t(3 * f)];
    const auto P = [&](int k) {
      const std::size_t v = std::size_t(t[k]);
      return Vec3f(m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]);
    };
    // towards an inner point and towards a point on an edge, from outside
    bool inner = true;
    for (const Vec3f& target : {0.5f * P(0) + 0.3f * P(1) + 0.2f * P(2), 0.5f * P(1) + 0.5f * P(2)}) {
      const Vec3f eye = 3.0f * target + Vec3f(0.1f, -0.2f, 0.3f);
      const Vec3f dir = glm::normalize(target - eye);
      // derivatives along the ray's origin and direction (Dual lanes)
      Vec3<S> o(eye.x, eye.y, eye.z), d(dir.x, dir.y, dir.z);
      if constexpr (ad::is_dual_v<S>)
        for (int c = 0; c < 3; ++c) {
          o[c].grad[c % S::lanes] = 1.0f;
          d[c].grad[(c + 1) % S::lanes] = 0.5f;
        }
      const auto a = scene::reevaluate_hit(unused, with, f, o, d);
      const auto b = scene::reevaluate_hit(unused, without, f, o, d);
      CHECK(a.hit.valid == b.hit.valid);
      CHECK(a.hit.inside == b.hit.inside);
      CHECK(a.point.valid == b.point.valid);
      hits += inner && a.hit.valid && a.hit.inside;
      check_same_bits(a.hit.t, b.hit.t);
      check_same_bits(a.hit.b1, b.hit.b1);
      check_same_bits(a.hit.b2, b.hit.b2);
      check_same_bits(a.point.p, b.point.p);
      check_same_bits(a.point.n, b.point.n);
      check_same_bits(a.point.ng, b.point.ng);
      const auto c = scene::surface_point(unused, with, f, S(0.25f), S(0.6f));
      const auto e = scene::surface_point(unused, without, f, S(0.25f), S(0.6f));
      CHECK(c.valid == e.valid);
      check_same_bits(c.p, e.p);
      check_same_bits(c.n, e.n);
      check_same_bits(c.ng, e.ng);
      inner = false;
    }
  }
  CHECK(hits == 80);  // every face of the sphere at its inner point; the face of zero area has no hit
}

TEST_CASE("triangle records follow the positions: update_normals remakes them, a stale record is seen") {
  TriangleMesh m = icosphere();
  const TriangleMesh before = m;
  for (float& x : m.positions) x *= 1.5f;
  // not yet remade: the records still hold the old vertices, and the hits differ
  ad::ParamReader<float> unused(nullptr);
  const Vec3f o(0.05f, 0.02f, 3.0f), d(0.0f, 0.0f, -1.0f);
  std::int32_t front = -1;
  for (std::int32_t f = 0; f < m.num_triangles() && front < 0; ++f) {
    MeshView arrays = m.view();
    arrays.records = nullptr;
    const auto h = scene::reevaluate_hit(unused, arrays, f, o, d);
    if (h.hit.valid && h.hit.inside && glm::dot(h.point.ng, d) < 0.0f) front = f;
  }
  REQUIRE(front >= 0);
  MeshView arrays = m.view();
  arrays.records = nullptr;
  const auto truth = scene::reevaluate_hit(unused, arrays, front, o, d);
  CHECK(scene::reevaluate_hit(unused, m.view(), front, o, d).hit.t != truth.hit.t);
  CHECK(scene::reevaluate_hit(unused, before.view(), front, o, d).hit.t ==
        scene::reevaluate_hit(unused, m.view(), front, o, d).hit.t);
  m.update_normals();
  CHECK(scene::reevaluate_hit(unused, m.view(), front, o, d).hit.t == truth.hit.t);
  // the front of the sphere of radius 1.5 (its facets lie within 10 % inside)
  CHECK(truth.hit.t > 3.0f - 1.5f);
  CHECK(truth.hit.t < 3.0f - 1.35f);
}
