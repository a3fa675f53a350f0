// Triangle mesh for the tracer: positions, vertex normals as DiffTrans defines
// them, and a hit re-evaluated on one triangle in S (Möller–Trumbore, normal).
#pragma once

#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#include "difftrans/ad/block_gradients.hpp"
#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/params.hpp"
#include "difftrans/core/parallel.hpp"
#include "difftrans/geometry/topology.hpp"
#include "difftrans/ad/param_source.hpp"

namespace difftrans::scene {

// Vertex normal (the paper): the mean of the unit normals of the faces around
// the vertex, normalized. Faces are counter-clockwise seen from the side the
// normal points to. Zero-area faces have no normal and are left out; a vertex
// whose face normals cancel gets the zero vector (the shading normal then
// falls back to the geometric one).
//
// Gradients through normals: a vertex normal depends on the vertex's whole
// one-ring. For rendering (plain S, or frozen positions) the normals come
// from the precomputed float array. When S carries derivatives and the
// positions are differentiable, the normals of the hit triangle's three
// vertices are recomputed in S from their one-rings (CSR vertex -> faces
// adjacency stored in the mesh), so the shading normal's derivative reaches
// every vertex of those rings. Both are computed by the same code, so their
// values agree. Positions read once are cached per hit (a small fixed cache),
// so a shared vertex becomes one leaf.

// One triangle's float data in one place, for the passes that read the
// positions as constants: its three vertices, their precomputed normals and
// its unit geometric normal, as the generic path computes them from the
// arrays (bit for bit), so that a hit reads one record instead of three
// indices, three positions and three normals scattered over the arrays, and
// does not recompute the face normal. Written by TriangleMesh::update_normals.
// 88 bytes: what Möller–Trumbore reads first comes first (bench_trace,
// primal against primal_arrays: the record is the hit's one cache miss
// on meshes larger than the cache).
struct TriangleRecord {
  float p[3][3];   // vertex positions
  float ng[3];     // unit geometric normal (winding order); zero for zero area
  std::int32_t area = 0;  // 1: the triangle has a non-zero area (SurfacePoint::valid)
  float n[3][3];   // vertex normals (the precomputed array's)
};

// A non-owning view of a mesh, copyable to a device. Arrays:
// positions 3 * num_vertices (x y z), triangles 3 * num_triangles,
// vertex_normals 3 * num_vertices, vf_offsets num_vertices + 1 and vf_faces:
// the faces around vertex v are vf_faces[vf_offsets[v] .. vf_offsets[v + 1]).
struct MeshView {
  ad::ParamSource positions;
  const std::int32_t* triangles = nullptr;
  const float* vertex_normals = nullptr;
  // The same normals as a parameter source: when differentiable (buffer >= 0)
  // an AD pass reads them as leaves of their own, and the caller folds their
  // gradient back into the positions once per pass (normals_backward), which
  // is far cheaper than recomputing every hit's one-rings on the tape.
  ad::ParamSource normals;
  const std::int32_t* vf_offsets = nullptr;
  const std::int32_t* vf_faces = nullptr;
  // num_triangles records made from `positions` and `vertex_normals`, or
  // nullptr. Read (see use_records) only where they equal what the arrays
  // give: float scalars, frozen positions and the precomputed normals.
  const TriangleRecord* records = nullptr;
  std::int32_t num_vertices = 0;
  std::int32_t num_triangles = 0;
};

enum class NormalMode : int {
  automatic,    // parameter when m.normals is differentiable; else one_ring when S carries derivatives
                // and positions are differentiable; else precomputed
  precomputed,  // the float array (constants: no derivative through normals)
  one_ring,     // recomputed in S from the one-rings
  parameter,    // read through the reader from m.normals (two-level: see MeshView::normals)
};

// Result of Möller–Trumbore in S.
template <class S>
struct TriangleHit {
  S t, b1, b2;  // ray parameter and barycentrics of p1, p2 (p = (1-b1-b2) p0 + b1 p1 + b2 p2); 0 when !valid
  bool valid;   // the triangle is not degenerate and the ray not parallel to it (values finite)
  bool inside;  // valid, b1 >= 0, b2 >= 0, b1 + b2 <= 1 and t >= 0 (on values)
};

// A point on the surface in S.
template <class S>
struct SurfacePoint {
  Vec3<S> p;   // position
  Vec3<S> n;   // unit shading normal (interpolated vertex normals)
  Vec3<S> ng;  // unit geometric normal (winding order); zero when !valid
  bool valid;  // the triangle has a non-zero area
};

// A ray's hit re-evaluated on a given triangle in S.
template <class S>
struct SurfaceHit {
  TriangleHit<S> hit;
  SurfacePoint<S> point;
};

// Relative threshold below which |det| counts as degenerate (zero area, or a
// ray parallel to the triangle's plane).
template <class T> inline constexpr T triangle_det_eps = T(8) * std::numeric_limits<T>::epsilon();

// Möller–Trumbore: where the ray o + t d meets the plane of (p0, p1, p2), with
// barycentrics, generic over S. Degenerate input gives valid = false and
// zeros, never NaN.
template <class S>
DT_HOST_DEVICE TriangleHit<S> intersect_triangle(const Vec3<S>& o, const Vec3<S>& d, const Vec3<S>& p0,
                                                 const Vec3<S>& p1, const Vec3<S>& p2) {
  using T = ad::scalar_t<S>;
  TriangleHit<S> h{S(0), S(0), S(0), false, false};
  const Vec3<S> e1 = p1 - p0, e2 = p2 - p0;
  const Vec3<S> pv = glm::cross(d, e2);
  const S det = glm::dot(e1, pv);
  const Vec3<T> e1v = ad::value_of(e1), e2v = ad::value_of(e2), dv = ad::value_of(d);
  const T scale = sqrt(glm::dot(e1v, e1v) * glm::dot(e2v, e2v) * glm::dot(dv, dv));
  const T detv = ad::value_of(det);
  if (!(abs(detv) > triangle_det_eps<T> * scale) || !isfinite(detv) || !isfinite(scale)) return h;
  const S inv = S(1) / det;
  const Vec3<S> s = o - p0;
  const Vec3<S> qv = glm::cross(s, e1);
  h.b1 = glm::dot(s, pv) * inv;
  h.b2 = glm::dot(d, qv) * inv;
  h.t = glm::dot(e2, qv) * inv;
  h.valid = isfinite(ad::value_of(h.t)) && isfinite(ad::value_of(h.b1)) && isfinite(ad::value_of(h.b2));
  if (!h.valid) {
    h.t = h.b1 = h.b2 = S(0);
    return h;
  }
  h.inside = h.b1 >= 0 && h.b2 >= 0 && ad::value_of(h.b1) + ad::value_of(h.b2) <= T(1) && h.t >= 0;
  return h;
}

namespace detail {

// Vertex positions read at most once per hit; beyond its capacity a read is
// simply repeated (correct, only more leaves).
template <class S, int N = 24>
struct PositionCache {
  std::int32_t id[N];
  Vec3<S> p[N];
  int count = 0;

  template <class Reader>
  DT_HOST_DEVICE Vec3<S> get(Reader& reader, const MeshView& m, std::int32_t v) {
    for (int k = 0; k < count; ++k)
      if (id[k] == v) return p[k];
    const Vec3<S> q = ad::load3<S>(reader, m.positions, v);
    if (count < N) {
      id[count] = v;
      p[count] = q;
      ++count;
    }
    return q;
  }
};

// cross(p1 - p0, p2 - p0), its unit vector, or false for zero area.
template <class S>
DT_HOST_DEVICE bool unit_face_normal(const Vec3<S>& p0, const Vec3<S>& p1, const Vec3<S>& p2, Vec3<S>& n) {
  using T = ad::scalar_t<S>;
  const Vec3<S> c = glm::cross(p1 - p0, p2 - p0);
  const S len2 = glm::dot(c, c);
  if (!(ad::value_of(len2) > T(0)) || !isfinite(ad::value_of(len2))) return false;
  n = c * (S(1) / sqrt(len2));
  return true;
}

// v / |v|, or false (v unchanged) when v is zero.
template <class S>
DT_HOST_DEVICE bool normalize_nonzero(Vec3<S>& v) {
  using T = ad::scalar_t<S>;
  const S len2 = glm::dot(v, v);
  if (!(ad::value_of(len2) > T(0)) || !isfinite(ad::value_of(len2))) return false;
  v = v * (S(1) / sqrt(len2));
  return true;
}

template <class S, class Reader, int N>
DT_HOST_DEVICE Vec3<S> vertex_normal_cached(Reader& reader, const MeshView& m, std::int32_t v,
                                            PositionCache<S, N>& cache) {
  Vec3<S> sum(S(0), S(0), S(0));
  if (!m.vf_offsets) return sum;
  const std::int32_t end = m.vf_offsets[v + 1];
  for (std::int32_t k = m.vf_offsets[v]; k < end; ++k) {
    const std::int32_t* tri = m.triangles + 3 * m.vf_faces[k];
    Vec3<S> n;
    if (unit_face_normal(cache.get(reader, m, tri[0]), cache.get(reader, m, tri[1]), cache.get(reader, m, tri[2]), n))
      sum += n;
  }
  if (!normalize_nonzero(sum)) return Vec3<S>(S(0), S(0), S(0));
  return sum;
}

}  // namespace detail

// The three vertex positions of triangle `tri`, read through the reader.
template <class S, class Reader>
DT_HOST_DEVICE void triangle_positions(Reader& reader, const MeshView& m, std::int32_t tri, Vec3<S> p[3]) {
  for (int k = 0; k < 3; ++k) p[k] = ad::load3<S>(reader, m.positions, m.triangles[3 * tri + k]);
}

// The normal of vertex v recomputed in S from its one-ring (needs the adjacency).
template <class S, class Reader>
DT_HOST_DEVICE Vec3<S> vertex_normal(Reader& reader, const MeshView& m, std::int32_t v) {
  detail::PositionCache<S> cache;
  return detail::vertex_normal_cached(reader, m, v, cache);
}

namespace detail {

template <class S>
DT_HOST_DEVICE bool use_normal_parameter(const MeshView& m, NormalMode mode) {
  if (!m.normals.values) return false;
  return mode == NormalMode::parameter || (mode == NormalMode::automatic && m.normals.differentiable());
}

template <class S>
DT_HOST_DEVICE bool use_one_ring(const MeshView& m, NormalMode mode) {
  if (mode == NormalMode::parameter) return false;
  if (mode == NormalMode::one_ring) return m.vf_offsets != nullptr;
  if (mode == NormalMode::automatic && m.normals.differentiable()) return false;
  if (mode == NormalMode::precomputed) return m.vertex_normals == nullptr && m.vf_offsets != nullptr;
  return (m.vertex_normals == nullptr || (ad::is_ad_v<S> && m.positions.differentiable())) &&
         m.vf_offsets != nullptr;
}

// Whether a pass in S reads a hit triangle from m.records: its scalar is
// float-valued (the records were computed in float), the positions are
// constants and the shading normals are the precomputed array's.
template <class S>
DT_HOST_DEVICE bool use_records(const MeshView& m, NormalMode mode) {
  if constexpr (!std::is_same_v<ad::scalar_t<S>, float>) {
    return false;
  } else {
    return m.records != nullptr && m.vertex_normals != nullptr && !m.positions.differentiable() &&
           !use_normal_parameter<S>(m, mode) && !use_one_ring<S>(m, mode);
  }
}

template <class S>
DT_HOST_DEVICE Vec3<S> record_vec(const float (&v)[3]) {
  return Vec3<S>(S(v[0]), S(v[1]), S(v[2]));
}

// The surface point at barycentrics (b1, b2) of the triangle with corners
// p[3], unit face normal ng (valid: a non-zero area; zero otherwise) and
// vertex normals vn[3]: what the arrays' path and the records' path share.
template <class S>
DT_HOST_DEVICE SurfacePoint<S> interpolate_surface_point(const Vec3<S> (&p)[3], const Vec3<S>& ng, bool valid,
                                                         const Vec3<S> (&vn)[3], const S& b1, const S& b2) {
  using T = ad::scalar_t<S>;
  const S b0 = T(1) - b1 - b2;
  SurfacePoint<S> sp;
  sp.p = p[0] * b0 + p[1] * b1 + p[2] * b2;
  sp.valid = valid;
  sp.ng = ng;
  sp.n = vn[0] * b0 + vn[1] * b1 + vn[2] * b2;
  if (!normalize_nonzero(sp.n)) sp.n = sp.ng;
  return sp;
}

// surface_point_cached's result, from a record (use_records).
template <class S>
DT_HOST_DEVICE SurfacePoint<S> surface_point_record(const TriangleRecord& r, const S& b1, const S& b2) {
  const Vec3<S> p[3] = {record_vec<S>(r.p[0]), record_vec<S>(r.p[1]), record_vec<S>(r.p[2])};
  const Vec3<S> vn[3] = {record_vec<S>(r.n[0]), record_vec<S>(r.n[1]), record_vec<S>(r.n[2])};
  return interpolate_surface_point(p, record_vec<S>(r.ng), r.area != 0, vn, b1, b2);
}

template <class S, class Reader, int N>
DT_HOST_DEVICE SurfacePoint<S> surface_point_cached(Reader& reader, const MeshView& m, std::int32_t tri,
                                                    const S& b1, const S& b2, NormalMode mode,
                                                    PositionCache<S, N>& cache) {
  const std::int32_t* idx = m.triangles + 3 * tri;
  const Vec3<S> p[3] = {cache.get(reader, m, idx[0]), cache.get(reader, m, idx[1]), cache.get(reader, m, idx[2])};
  Vec3<S> ng;
  const bool valid = unit_face_normal(p[0], p[1], p[2], ng);
  if (!valid) ng = Vec3<S>(S(0), S(0), S(0));
  Vec3<S> vn[3];
  if (use_normal_parameter<S>(m, mode)) {
    for (int k = 0; k < 3; ++k) vn[k] = ad::load3<S>(reader, m.normals, idx[k]);
  } else if (use_one_ring<S>(m, mode)) {
    for (int k = 0; k < 3; ++k) vn[k] = vertex_normal_cached(reader, m, idx[k], cache);
  } else if (m.vertex_normals) {
    for (int k = 0; k < 3; ++k) {
      const float* q = m.vertex_normals + 3 * idx[k];
      vn[k] = Vec3<S>(S(q[0]), S(q[1]), S(q[2]));
    }
  } else {
    for (int k = 0; k < 3; ++k) vn[k] = ng;
  }
  return interpolate_surface_point(p, ng, valid, vn, b1, b2);
}

}  // namespace detail

// Position, shading normal and geometric normal at barycentrics (b1, b2) of
// triangle `tri`, generic over S. Vertices are re-read through the reader.
template <class S, class Reader>
DT_HOST_DEVICE SurfacePoint<S> surface_point(Reader& reader, const MeshView& m, std::int32_t tri, const S& b1,
                                             const S& b2, NormalMode mode = NormalMode::automatic) {
  if (detail::use_records<S>(m, mode)) return detail::surface_point_record(m.records[tri], b1, b2);
  detail::PositionCache<S> cache;
  return detail::surface_point_cached(reader, m, tri, b1, b2, mode, cache);
}

// The hit of ray (o, d) on triangle `tri` (chosen in float by a BVH),
// re-evaluated in S: t and barycentrics by Möller–Trumbore on the re-read
// vertices, then the surface point there. Edge and vertex hits are ordinary
// (no range test is applied); hit.valid is false for a degenerate triangle.
template <class S, class Reader>
DT_HOST_DEVICE SurfaceHit<S> reevaluate_hit(Reader& reader, const MeshView& m, std::int32_t tri, const Vec3<S>& o,
                                            const Vec3<S>& d, NormalMode mode = NormalMode::automatic) {
  SurfaceHit<S> r;
  if (detail::use_records<S>(m, mode)) {
    const TriangleRecord& rec = m.records[tri];
    r.hit = intersect_triangle(o, d, detail::record_vec<S>(rec.p[0]), detail::record_vec<S>(rec.p[1]),
                               detail::record_vec<S>(rec.p[2]));
    r.point = detail::surface_point_record(rec, r.hit.b1, r.hit.b2);
    if (!r.hit.valid) r.point.valid = false;
    return r;
  }
  detail::PositionCache<S> cache;
  const std::int32_t* idx = m.triangles + 3 * tri;
  r.hit = intersect_triangle(o, d, cache.get(reader, m, idx[0]), cache.get(reader, m, idx[1]),
                             cache.get(reader, m, idx[2]));
  r.point = detail::surface_point_cached(reader, m, tri, r.hit.b1, r.hit.b2, mode, cache);
  if (!r.hit.valid) r.point.valid = false;
  return r;
}

// ------------------------------------------------------------ host owner

// Owns a mesh's arrays, builds the vertex -> faces adjacency and the
// precomputed normals. Call update_normals() after changing positions.
class TriangleMesh {
 public:
  std::vector<float> positions;          // 3 per vertex
  std::vector<std::int32_t> triangles;   // 3 per triangle
  std::vector<float> vertex_normals;     // 3 per vertex
  std::vector<std::int32_t> vf_offsets;  // num_vertices + 1
  std::vector<std::int32_t> vf_faces;
  std::vector<TriangleRecord> records;   // num_triangles, made with the normals

  TriangleMesh() = default;
  TriangleMesh(std::vector<float> pos, std::vector<std::int32_t> tris)
      : positions(std::move(pos)), triangles(std::move(tris)) {
    build_adjacency();
    update_normals();
  }

  std::int32_t num_vertices() const { return std::int32_t(positions.size() / 3); }
  std::int32_t num_triangles() const { return std::int32_t(triangles.size() / 3); }

  // CSR vertex -> faces (geometry::vertex_faces: increasing face order, a
  // collapsed face listed once per vertex).
  void build_adjacency() {
    geometry::VertexFaces vf = geometry::vertex_faces(triangles.data(), num_triangles(), num_vertices());
    vf_offsets = std::move(vf.offsets);
    vf_faces = std::move(vf.faces);
  }

  // Recomputes the float vertex normals from the positions (same code as the
  // generic path, so the values match what one_ring gives in float), then
  // the triangle records from both.
  void update_normals() {
    vertex_normals.assign(positions.size(), 0.0f);
    records.clear();
    const MeshView m = view();
    ad::ParamReader<float> unused(nullptr);  // the positions are read as constants
    for (std::int32_t v = 0; v < num_vertices(); ++v) {
      const Vec3f n = vertex_normal<float>(unused, m, v);
      for (int c = 0; c < 3; ++c) vertex_normals[std::size_t(3 * v + c)] = n[c];
    }
    records.resize(std::size_t(num_triangles()));
    for (std::int32_t f = 0; f < num_triangles(); ++f) {
      TriangleRecord& r = records[std::size_t(f)];
      Vec3f p[3];
      for (int k = 0; k < 3; ++k) {
        const std::size_t v = std::size_t(triangles[std::size_t(3 * f + k)]);
        for (int c = 0; c < 3; ++c) {
          r.p[k][c] = positions[3 * v + std::size_t(c)];
          r.n[k][c] = vertex_normals[3 * v + std::size_t(c)];
        }
        p[k] = Vec3f(r.p[k][0], r.p[k][1], r.p[k][2]);
      }
      Vec3f ng(0.0f);
      r.area = detail::unit_face_normal(p[0], p[1], p[2], ng) ? 1 : 0;
      if (!r.area) ng = Vec3f(0.0f);
      for (int c = 0; c < 3; ++c) r.ng[c] = ng[c];
    }
  }

  // Adds to grad_positions the gradient that flows through the vertex
  // normals, given the gradient w.r.t. them (3 per vertex): the second level
  // of MeshView::normals. Each vertex's normal is recomputed from its one-ring
  // on a small tape; vertices with a zero normal gradient cost nothing.
  void normals_backward(const float* grad_normals, float* grad_positions) const {
    using V = ad::Var<float>;
    ad::ParamSet set;
    set.buffers[0].values = positions.data();
    set.buffers[0].size = std::int32_t(positions.size());
    set.buffers[0].gradient = grad_positions;
    const MeshView m = view(0);
    ad::BlockGradients blocks(set, num_vertices(), 32, 256);  // a fixed order of sums
    parallel_for(blocks.count(), 1, [&](std::int64_t kb, std::int64_t ke, int) {
      ad::Tape<float> tape(1 << 14);
      std::vector<ad::LeafRecord> log(1 << 12);
      for (std::int64_t k = kb; k < ke; ++k) {
        ad::ParamReader<V> reader(&blocks.set(k), &tape, log.data(), std::int32_t(log.size()));
        for (std::int64_t v = blocks.begin(k); v < blocks.end(k); ++v) {
          const float* g = grad_normals + 3 * v;
          if (g[0] == 0.0f && g[1] == 0.0f && g[2] == 0.0f) continue;
          tape.reset();
          reader.clear();
          const Vec3<V> n = vertex_normal<V>(reader, m, std::int32_t(v));
          if (tape.overflowed() || reader.overflowed()) continue;  // valence beyond 1000: skipped
          tape.zero_adjoints();
          for (int c = 0; c < 3; ++c) tape.seed(n[c], g[c]);
          tape.propagate();
          reader.scatter();
        }
      }
    });
    blocks.reduce();
  }

  // The view for the generic path; position_buffer >= 0 makes the positions
  // that parameter buffer of the pass's ParamSet, normal_buffer >= 0 the
  // vertex normals (two-level normals, see MeshView::normals).
  MeshView view(int position_buffer = -1, int normal_buffer = -1) const {
    MeshView m;
    m.positions = ad::ParamSource{positions.data(), std::int32_t(positions.size()), position_buffer};
    m.triangles = triangles.data();
    m.vertex_normals = vertex_normals.size() == positions.size() ? vertex_normals.data() : nullptr;
    m.normals = ad::ParamSource{m.vertex_normals, m.vertex_normals ? std::int32_t(vertex_normals.size()) : 0,
                            m.vertex_normals ? normal_buffer : -1};
    m.vf_offsets = vf_offsets.empty() ? nullptr : vf_offsets.data();
    m.vf_faces = vf_faces.data();
    m.records = records.size() == std::size_t(num_triangles()) && m.vertex_normals ? records.data() : nullptr;
    m.num_vertices = num_vertices();
    m.num_triangles = num_triangles();
    return m;
  }
};

}  // namespace difftrans::scene
