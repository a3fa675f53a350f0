// FlexiCubes (Shen et al. 2023): dual-marching-cubes extraction of a triangle mesh from a
// deformable grid with an SDF and per-cube weights; vertex positions generic over S.
#pragma once

#include <cstdint>
#include <type_traits>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/params.hpp"
#include "difftrans/geometry/flexicubes_tables.hpp"
#include "difftrans/ad/param_source.hpp"

namespace difftrans::geometry {

// The method, as implemented here.
//
// Grid: res³ cubes over the box [lo, hi], (res + 1)³ grid vertices. Vertex
// (i, j, k) has index i + (res + 1) (j + (res + 1) k), cube (i, j, k) has index
// i + res (j + res k) and corners (i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1)).
//
// Unknowns (raw, unbounded; each a flat float array, see FlexiCubesInputs):
//   sdf     s_v, one per grid vertex; s < 0 is inside.
//   deform  δ_v, three per vertex; the vertex moves to
//           x_v = grid_v + deform_bound · cell ⊙ tanh(δ_v), less than half a cell.
//   alpha   8 per cube (per corner), squashed α = 0.99 tanh(a) + 1 ∈ (0.01, 1.99).
//   beta    12 per cube (per edge), squashed β = 0.99 tanh(b) + 1.
//   gamma   1 per cube, squashed γ = 0.99 σ(g) + 0.005 ∈ (0.005, 0.995).
//
// Crossing point of a sign-changing edge (a, b) in a cube: the zero of the
// linear interpolation of the α-scaled values s̃_a = α_a s_a, s̃_b = α_b s_b
// between the deformed endpoints. With t the zero of s̃_a + t (s̃_b − s̃_a),
//   t = s̃_a / (s̃_a − s̃_b),   u = x_a + t (x_b − x_a) = (s̃_a x_b − s̃_b x_a) / (s̃_a − s̃_b),
// the paper's form. s̃_a and s̃_b have opposite signs (or one is 0) and α > 0,
// so the denominator never vanishes and t ∈ [0, 1]. α is the cube's own, so
// the cubes around one grid edge may place its crossing differently.
//
// Dual vertex: each group of sign-changing edges (flexicubes_tables.hpp) is
// one vertex, the β-weighted mean v = Σ β_e u_e / Σ β_e of its crossings.
// Cases whose rule merges the two edge pairs of an ambiguous face into one
// vertex (36 cases) look at the cube across that face: if it merged the same
// face, both use the other split of it, so that a mesh edge is never shared by
// four faces.
//
// Faces: every sign-changing grid edge inside the grid (four cubes around it)
// gives the quad of the four cubes' dual vertices of that edge, ordered
// counter-clockwise seen from the outside: when the edge runs from inside to
// outside along +axis the quad turns positively about +axis. Split:
//   four_triangles (default; the paper's training split): a centre vertex
//     c = (γ02 m02 + γ13 m13) / (γ02 + γ13), m02, m13 the midpoints of the two
//     diagonals, γ02 = γ0 γ2, γ13 = γ1 γ3 (γ of each dual vertex's cube), and
//     the triangles (0 1 c) (1 2 c) (2 3 c) (3 0 c): γ gets gradients.
//   two_triangles (the paper's inference split): cut along the diagonal with
//     the larger γ product: (0 1 2) (0 2 3) when γ02 > γ13, else (1 2 3) (1 3 0).
// Sign-changing edges on the grid's boundary give no face: keep the border
// values positive for a closed mesh.

enum class QuadSplit : int { four_triangles, two_triangles };

struct FlexiCubesOptions {
  QuadSplit split = QuadSplit::four_triangles;
  // Resolve ambiguous faces merged on both sides (always on in use; off only
  // to show what the check prevents).
  bool resolve_ambiguous_faces = true;
};

// Deformations reach at most this fraction of a cell: just under half.
template <class T> inline constexpr T flexicubes_deform_bound = T(0.5) * (T(1) - T(1e-4));

struct FlexiCubesGrid {
  std::int32_t res = 1;  // cubes per axis
  Vec3f lo{-1.0f}, hi{1.0f};

  DT_HOST_DEVICE std::int32_t num_vertices() const { return (res + 1) * (res + 1) * (res + 1); }
  DT_HOST_DEVICE std::int32_t num_cubes() const { return res * res * res; }
  DT_HOST_DEVICE std::int32_t vertex_index(int i, int j, int k) const { return i + (res + 1) * (j + (res + 1) * k); }
  DT_HOST_DEVICE std::int32_t cube_index(int i, int j, int k) const { return i + res * (j + res * k); }
  DT_HOST_DEVICE Vec3f cell() const { return (hi - lo) / float(res); }
  // Undeformed position of vertex (i, j, k).
  DT_HOST_DEVICE Vec3f vertex_position(int i, int j, int k) const {
    return lo + (hi - lo) * (Vec3f(float(i), float(j), float(k)) / float(res));
  }
};

// The unknowns, each a flat float array (ad::ParamSource: differentiable
// through the reader when its buffer is >= 0, else constants). Layouts:
// sdf[v], deform[3 v + axis], alpha[8 c + corner], beta[12 c + edge],
// gamma[c], v a vertex index and c a cube index. A source without values is
// read as raw 0 everywhere: no deformation, α = β = 1, γ = 0.505. The sdf
// values are required: every discrete decision is taken on them.
struct FlexiCubesInputs {
  ad::ParamSource sdf, deform, alpha, beta, gamma;
};

// The extracted mesh.
template <class S>
struct FlexiCubesMesh {
  std::vector<Vec3<S>> vertices;        // dual vertices first, then (four_triangles) one centre per quad
  std::vector<std::int32_t> triangles;  // 3 per triangle, counter-clockwise seen from outside (s > 0)
  std::int32_t num_dual_vertices = 0;
  std::vector<std::int32_t> dual_vertex_cube;  // the cube of each dual vertex
  std::vector<std::int32_t> quads;             // 4 dual vertices per quad, in the outward order
  // 2 per quad: the grid vertices (lower, upper along its axis) of the sign-changing edge
  std::vector<std::int32_t> quad_edges;
  int triangles_per_quad = 4;  // the triangles of quad q are triangles_per_quad · q + [0, triangles_per_quad)

  std::int32_t num_triangles() const { return std::int32_t(triangles.size() / 3); }
  std::int32_t num_quads() const { return std::int32_t(quads.size() / 4); }
};

// ---------------------------------------------------------- the continuous parts

template <class S>
DT_HOST_DEVICE S flexicubes_squash_weight(const S& raw) {  // α, β = 0.99 tanh(raw) + 1
  using T = ad::scalar_t<S>;
  return S(T(0.99) * tanh(raw) + T(1));
}

template <class S>
DT_HOST_DEVICE S flexicubes_squash_gamma(const S& raw) {  // γ = 0.99 σ(raw) + 0.005
  using T = ad::scalar_t<S>;
  return S(T(0.99) * sigmoid(raw) + T(0.005));
}

// Crossing of edge (a, b): x_a + t (x_b − x_a), t = α_a s_a / (α_a s_a − α_b s_b).
template <class S>
DT_HOST_DEVICE Vec3<S> flexicubes_crossing(const Vec3<S>& xa, const S& sa, const S& alpha_a, const Vec3<S>& xb,
                                           const S& sb, const S& alpha_b) {
  const S wa = alpha_a * sa, wb = alpha_b * sb;
  const S t = wa / (wa - wb);
  return xa + t * (xb - xa);
}

// Quad centre for the four-triangle split.
template <class S>
DT_HOST_DEVICE Vec3<S> flexicubes_quad_centre(const Vec3<S>* p, const S* gamma) {
  using T = ad::scalar_t<S>;
  const S g02 = gamma[0] * gamma[2], g13 = gamma[1] * gamma[3];
  const S w02 = T(0.5) * g02 / (g02 + g13), w13 = T(0.5) * g13 / (g02 + g13);
  return w02 * (p[0] + p[2]) + w13 * (p[1] + p[3]);
}

namespace detail {

// raw 0 when a source has no values.
template <class S, class Reader>
S fc_read(Reader& reader, const ad::ParamSource& src, std::int32_t index) {
  if (src.buffer >= 0) return S(reader.read(src.buffer, index));
  if (!src.values) return S(0);
  return S(src.values[index]);
}

// Reads nothing: every source treated as constants.
struct FcConstantReader {
  float read(int, std::int32_t) const { return 0.0f; }
};

}  // namespace detail

// ---------------------------------------------------------- the discrete parts

// Which configuration (flexicubes_tables.configs) every cube uses, the first
// dual vertex of each cube (-1: none) and the quads. Depends on SDF values only.
struct FlexiCubesTopology {
  std::vector<std::uint16_t> config;       // per cube
  std::vector<std::int32_t> first_vertex;  // per cube
  std::vector<std::int32_t> vertex_cube;   // per dual vertex
  std::vector<std::int32_t> quads;         // 4 per quad
  std::vector<std::int32_t> quad_edges;    // 2 per quad
};

inline FlexiCubesTopology flexicubes_topology(const FlexiCubesGrid& grid, const float* sdf,
                                              const FlexiCubesOptions& options = {}) {
  const FlexiCubesTables& tab = flexicubes_tables;
  const int R = grid.res, V = R + 1;
  FlexiCubesTopology top;
  std::vector<std::uint8_t> inside(std::size_t(grid.num_vertices()));
  for (std::size_t v = 0; v < inside.size(); ++v) inside[v] = sdf[v] < 0.0f ? 1 : 0;

  // Case ids: corner c of cube (i, j, k) is vertex (i, j, k) + offset(c).
  top.config.assign(std::size_t(grid.num_cubes()), 0);
  const std::int32_t dy = V, dz = V * V;
  for (int k = 0; k < R; ++k)
    for (int j = 0; j < R; ++j) {
      const std::uint8_t* p = inside.data() + grid.vertex_index(0, j, k);
      std::uint16_t* out = top.config.data() + grid.cube_index(0, j, k);
      for (int i = 0; i < R; ++i, ++p)
        out[i] = std::uint16_t(p[0] | p[1] << 1 | p[dy] << 2 | p[dy + 1] << 3 | p[dz] << 4 | p[dz + 1] << 5 |
                               p[dz + dy] << 6 | p[dz + dy + 1] << 7);
    }

  // Merged ambiguous faces on both sides: both cubes take the other split.
  if (options.resolve_ambiguous_faces) {
    for (int k = 0; k < R; ++k)
      for (int j = 0; j < R; ++j)
        for (int i = 0; i < R; ++i) {
          std::uint16_t& cfg = top.config[std::size_t(grid.cube_index(i, j, k))];
          const int f = tab.merged_face[cfg & 255];
          if (f < 0) continue;
          int n[3] = {i, j, k};
          n[f / 2] += f % 2 ? 1 : -1;
          if (n[f / 2] < 0 || n[f / 2] >= R) continue;
          const std::uint16_t other = top.config[std::size_t(grid.cube_index(n[0], n[1], n[2]))] & 255;
          if (tab.merged_face[other] >= 0) cfg = std::uint16_t((cfg & 255) | 256);
        }
  }

  // Dual vertices, numbered cube by cube.
  top.first_vertex.assign(std::size_t(grid.num_cubes()), -1);
  std::int32_t count = 0;
  for (std::int32_t c = 0; c < grid.num_cubes(); ++c) {
    const int n = tab.configs[top.config[std::size_t(c)]].num_groups;
    if (n == 0) continue;
    top.first_vertex[std::size_t(c)] = count;
    for (int g = 0; g < n; ++g) top.vertex_cube.push_back(c);
    count += n;
  }

  // Quads around interior sign-changing edges.
  const std::int32_t vstep[3] = {1, dy, dz};
  for (int k = 0; k < V; ++k)
    for (int j = 0; j < V; ++j)
      for (int i = 0; i < V; ++i) {
        const int x[3] = {i, j, k};
        const std::int32_t a = grid.vertex_index(i, j, k);
        for (int axis = 0; axis < 3; ++axis) {
          const int u = (axis + 1) % 3, w = (axis + 2) % 3;
          if (x[axis] >= R || x[u] < 1 || x[u] >= R || x[w] < 1 || x[w] >= R) continue;
          const std::int32_t b = a + vstep[axis];
          if (inside[std::size_t(a)] == inside[std::size_t(b)]) continue;
          // cubes at (u, w) offsets (-1,-1) (0,-1) (0,0) (-1,0): counter-clockwise about +axis
          static constexpr int du[4] = {-1, 0, 0, -1}, dw[4] = {-1, -1, 0, 0};
          std::int32_t q[4];
          for (int m = 0; m < 4; ++m) {
            int cx[3];
            cx[axis] = x[axis];
            cx[u] = x[u] + du[m];
            cx[w] = x[w] + dw[m];
            const std::int32_t cube = grid.cube_index(cx[0], cx[1], cx[2]);
            const int local = tab.edge_at[axis][-du[m]][-dw[m]];
            q[m] = top.first_vertex[std::size_t(cube)] + tab.configs[top.config[std::size_t(cube)]].edge_group[local];
          }
          // inside → outside along +axis: outward is +axis; else reverse
          if (inside[std::size_t(a)]) {
            top.quads.insert(top.quads.end(), {q[0], q[1], q[2], q[3]});
          } else {
            top.quads.insert(top.quads.end(), {q[3], q[2], q[1], q[0]});
          }
          top.quad_edges.insert(top.quad_edges.end(), {a, b});
        }
      }
  return top;
}

// ---------------------------------------------------------- extraction

// Extracts the mesh. Every unknown is read through `reader` (reader.read(buffer,
// index), e.g. ad::ParamReader<S>) when its source is differentiable, once per
// grid vertex (sdf, deform) or cube (weights) used. With Var, the positions
// live on the reader's tape; check tape->overflowed() afterwards.
template <class S, class Reader, std::enable_if_t<!std::is_same_v<std::decay_t<Reader>, FlexiCubesOptions>, int> = 0>
FlexiCubesMesh<S> flexicubes_extract(const FlexiCubesGrid& grid, const FlexiCubesInputs& in, Reader& reader,
                                     const FlexiCubesOptions& options = {}) {
  using T = ad::scalar_t<S>;
  const FlexiCubesTables& tab = flexicubes_tables;
  FlexiCubesTopology top = flexicubes_topology(grid, in.sdf.values, options);
  FlexiCubesMesh<S> mesh;
  mesh.num_dual_vertices = std::int32_t(top.vertex_cube.size());
  mesh.dual_vertex_cube = std::move(top.vertex_cube);
  mesh.triangles_per_quad = options.split == QuadSplit::four_triangles ? 4 : 2;

  // Grid vertices used by some crossing, each read once: value and deformed position.
  const int R = grid.res, V = R + 1;
  const std::int32_t corner_step[8] = {0, 1, V, V + 1, V * V, V * V + 1, V * V + V, V * V + V + 1};
  std::vector<std::int32_t> slot(std::size_t(grid.num_vertices()), -1);
  std::vector<S> s_slot;
  std::vector<Vec3<S>> x_slot;
  const Vec3f cell = grid.cell();
  const Vec3<T> reach = Vec3<T>(cell) * flexicubes_deform_bound<T>;
  const bool has_deform = in.deform.values || in.deform.buffer >= 0;
  auto vertex_slot = [&](std::int32_t v) {
    std::int32_t& sl = slot[std::size_t(v)];
    if (sl >= 0) return sl;
    sl = std::int32_t(s_slot.size());
    s_slot.push_back(detail::fc_read<S>(reader, in.sdf, v));
    const int i = v % V, j = (v / V) % V, k = v / (V * V);
    const Vec3f g = grid.vertex_position(i, j, k);
    Vec3<S> x;
    for (int a = 0; a < 3; ++a)
      x[a] = has_deform ? S(T(g[a]) + reach[a] * tanh(detail::fc_read<S>(reader, in.deform, 3 * v + a))) : S(g[a]);
    x_slot.push_back(x);
    return sl;
  };

  // Dual vertices, cube by cube.
  mesh.vertices.resize(std::size_t(mesh.num_dual_vertices));
  std::vector<S> gamma(std::size_t(mesh.num_dual_vertices));
  const bool has_alpha = in.alpha.values || in.alpha.buffer >= 0;
  const bool has_beta = in.beta.values || in.beta.buffer >= 0;
  for (std::int32_t c = 0; c < grid.num_cubes(); ++c) {
    const std::int32_t first = top.first_vertex[std::size_t(c)];
    if (first < 0) continue;
    const FlexiCubesCase& cs = tab.configs[top.config[std::size_t(c)]];
    const std::int32_t base = grid.vertex_index(c % R, (c / R) % R, c / (R * R));
    std::int32_t sl[8];
    S alpha[8];
    std::uint16_t edges = 0;
    for (int g = 0; g < cs.num_groups; ++g) edges = std::uint16_t(edges | cs.group_edges[g]);
    for (int corner = 0; corner < 8; ++corner) {
      bool used = false;
      for (int e = 0; e < 12; ++e)
        used = used || ((edges >> e & 1) && (flexicubes_edge_corners[e][0] == corner || flexicubes_edge_corners[e][1] == corner));
      if (!used) continue;
      sl[corner] = vertex_slot(base + corner_step[corner]);
      alpha[corner] = has_alpha ? flexicubes_squash_weight(detail::fc_read<S>(reader, in.alpha, 8 * c + corner)) : S(1);
    }
    const S g = flexicubes_squash_gamma(detail::fc_read<S>(reader, in.gamma, c));
    for (int grp = 0; grp < cs.num_groups; ++grp) {
      Vec3<S> sum(S(0));
      S wsum(0);
      for (int e = 0; e < 12; ++e) {
        if (!(cs.group_edges[grp] >> e & 1)) continue;
        const int ca = flexicubes_edge_corners[e][0], cb = flexicubes_edge_corners[e][1];
        const std::int32_t ia = sl[ca], ib = sl[cb];
        const Vec3<S> u = flexicubes_crossing(x_slot[std::size_t(ia)], s_slot[std::size_t(ia)], alpha[ca],
                                              x_slot[std::size_t(ib)], s_slot[std::size_t(ib)], alpha[cb]);
        if (has_beta) {
          const S beta = flexicubes_squash_weight(detail::fc_read<S>(reader, in.beta, 12 * c + e));
          sum += beta * u;
          wsum += beta;
        } else {
          sum += u;
          wsum += S(1);
        }
      }
      mesh.vertices[std::size_t(first + grp)] = sum / wsum;
      gamma[std::size_t(first + grp)] = g;
    }
  }

  // Triangles.
  const std::int32_t nq = std::int32_t(top.quads.size() / 4);
  mesh.triangles.reserve(std::size_t(nq) * std::size_t(3 * mesh.triangles_per_quad));
  if (options.split == QuadSplit::four_triangles) mesh.vertices.reserve(mesh.vertices.size() + std::size_t(nq));
  for (std::int32_t qi = 0; qi < nq; ++qi) {
    const std::int32_t* q = top.quads.data() + 4 * qi;
    const S gq[4] = {gamma[std::size_t(q[0])], gamma[std::size_t(q[1])], gamma[std::size_t(q[2])],
                     gamma[std::size_t(q[3])]};
    if (options.split == QuadSplit::four_triangles) {
      const Vec3<S> p[4] = {mesh.vertices[std::size_t(q[0])], mesh.vertices[std::size_t(q[1])],
                            mesh.vertices[std::size_t(q[2])], mesh.vertices[std::size_t(q[3])]};
      const std::int32_t centre = std::int32_t(mesh.vertices.size());
      mesh.vertices.push_back(flexicubes_quad_centre(p, gq));
      for (int m = 0; m < 4; ++m) mesh.triangles.insert(mesh.triangles.end(), {q[m], q[(m + 1) % 4], centre});
    } else {
      const T g02 = value_of(gq[0]) * value_of(gq[2]), g13 = value_of(gq[1]) * value_of(gq[3]);
      if (g02 > g13)
        mesh.triangles.insert(mesh.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
      else
        mesh.triangles.insert(mesh.triangles.end(), {q[1], q[2], q[3], q[1], q[3], q[0]});
    }
  }
  mesh.quads = std::move(top.quads);
  mesh.quad_edges = std::move(top.quad_edges);
  return mesh;
}

// All unknowns as constants of S (no reader, no derivatives).
template <class S>
FlexiCubesMesh<S> flexicubes_extract(const FlexiCubesGrid& grid, FlexiCubesInputs in,
                                     const FlexiCubesOptions& options = {}) {
  for (ad::ParamSource* p : {&in.sdf, &in.deform, &in.alpha, &in.beta, &in.gamma}) p->buffer = -1;
  detail::FcConstantReader reader;
  return flexicubes_extract<S>(grid, in, reader, options);
}

}  // namespace difftrans::geometry
