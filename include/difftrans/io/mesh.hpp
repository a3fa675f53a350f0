// Plain triangle mesh as the io functions read and write it, its validation
// (errors for bad indices and non-finite vertices, warnings for degenerate and
// non-manifold faces), and the unit-box normalization of docs/conventions.md.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/core/vec.hpp"
#include "difftrans/io/error.hpp"

namespace difftrans::io {

// Float positions and int32 triangle indices (counter-clockwise = outward).
struct Mesh {
  std::vector<Vec3f> positions;
  std::vector<Vec3i> triangles;
};

// The positions as x, y, z per vertex and the triangles as three indices
// each: the flat arrays the tracer's meshes (scene::TriangleMesh) are made of.
inline std::vector<float> flat_positions(const Mesh& mesh) {
  std::vector<float> out;
  out.reserve(mesh.positions.size() * 3);
  for (const Vec3f& p : mesh.positions) out.insert(out.end(), {p.x, p.y, p.z});
  return out;
}
inline std::vector<std::int32_t> flat_triangles(const Mesh& mesh) {
  std::vector<std::int32_t> out;
  out.reserve(mesh.triangles.size() * 3);
  for (const Vec3i& t : mesh.triangles) out.insert(out.end(), {t.x, t.y, t.z});
  return out;
}

// Axis-aligned box; empty when lo > hi.
struct Box {
  Vec3d lo{std::numeric_limits<double>::infinity()};
  Vec3d hi{-std::numeric_limits<double>::infinity()};
  bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  Vec3d centre() const { return 0.5 * (lo + hi); }
  Vec3d size() const { return hi - lo; }
};

// Box of the vertices that triangles use (of all vertices if there are no triangles).
inline Box bounding_box(const Mesh& mesh) {
  Box box;
  const auto grow = [&](const Vec3f& p) {
    box.lo = glm::min(box.lo, Vec3d(p));
    box.hi = glm::max(box.hi, Vec3d(p));
  };
  const int n = int(mesh.positions.size());
  if (mesh.triangles.empty()) {
    for (const auto& p : mesh.positions) grow(p);
  } else {
    for (const auto& t : mesh.triangles)
      for (int k = 0; k < 3; ++k)
        if (t[k] >= 0 && t[k] < n) grow(mesh.positions[t[k]]);
  }
  return box;
}

// p -> (p - centre) * scale. docs/conventions.md: centre of the bounding box to the
// origin, longest side 1. Computed on one mesh (the ground truth), it can be
// applied to another (the prediction).
struct UnitBoxTransform {
  Vec3d centre{0.0};
  double scale = 1.0;
  Vec3f apply(const Vec3f& p) const { return Vec3f((Vec3d(p) - centre) * scale); }
  Vec3f invert(const Vec3f& p) const { return Vec3f(Vec3d(p) / scale + centre); }
};

inline UnitBoxTransform unit_box_transform(const Mesh& mesh) {
  const Box box = bounding_box(mesh);
  if (box.empty()) throw std::invalid_argument("unit_box_transform: the mesh has no vertices");
  const Vec3d size = box.size();
  const double longest = std::max(size.x, std::max(size.y, size.z));
  if (!(longest > 0.0) || !std::isfinite(longest))
    throw std::invalid_argument("unit_box_transform: the mesh's bounding box has no extent");
  return {box.centre(), 1.0 / longest};
}

inline void apply_transform(const UnitBoxTransform& transform, Mesh& mesh) {
  for (auto& p : mesh.positions) p = transform.apply(p);
}

// Normalizes the mesh in place and returns the transform it applied.
inline UnitBoxTransform normalize_to_unit_box(Mesh& mesh) {
  const UnitBoxTransform transform = unit_box_transform(mesh);
  apply_transform(transform, mesh);
  return transform;
}

namespace detail {

// At most this many locations are listed per kind of warning.
inline constexpr int max_listed_warnings = 5;

inline std::string list_more(long count, int listed) {
  return count > listed ? " (and " + std::to_string(count - listed) + " more)" : "";
}

}  // namespace detail

// Validates a mesh read from `file`. Throws Error for an index out of range or
// a non-finite vertex; returns warnings for degenerate faces (repeated vertex,
// zero area), non-manifold edges (shared by more than two faces), boundary
// edges and inconsistently oriented neighbours. `describe_triangle` names a
// triangle for messages (e.g. "face on line 12"); by default "triangle i".
inline std::vector<std::string> check_mesh(
    const Mesh& mesh, const std::filesystem::path& file,
    const std::function<std::string(int)>& describe_triangle = {}) {
  const auto where = [&](int t) {
    return describe_triangle ? describe_triangle(t) : "triangle " + std::to_string(t);
  };
  const long nv = long(mesh.positions.size());
  for (long i = 0; i < nv; ++i) {
    const Vec3f& p = mesh.positions[size_t(i)];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      throw Error(file, "vertex " + std::to_string(i) + " has a non-finite coordinate (" +
                            std::to_string(p.x) + ", " + std::to_string(p.y) + ", " +
                            std::to_string(p.z) + ")");
  }
  const int nt = int(mesh.triangles.size());
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const int i = mesh.triangles[size_t(t)][k];
      if (i < 0 || i >= nv)
        throw Error(file, where(t) + ": vertex index " + std::to_string(i) + " is out of range [0, " +
                              std::to_string(nv) + ")");
    }

  std::vector<std::string> warnings;
  const std::string prefix = file.string() + ": ";
  // Degenerate faces.
  long degenerate = 0;
  std::string listed;
  for (int t = 0; t < nt; ++t) {
    const Vec3i& f = mesh.triangles[size_t(t)];
    std::string why;
    if (f.x == f.y || f.y == f.z || f.x == f.z) {
      why = "repeated vertex";
    } else {
      const Vec3d a(mesh.positions[size_t(f.x)]), b(mesh.positions[size_t(f.y)]), c(mesh.positions[size_t(f.z)]);
      const Vec3d e1 = b - a, e2 = c - a;
      const double scale = std::max(glm::dot(e1, e1), std::max(glm::dot(e2, e2), glm::dot(c - b, c - b)));
      if (glm::length(glm::cross(e1, e2)) <= 1e-10 * scale) why = "zero area";
    }
    if (why.empty()) continue;
    if (degenerate < detail::max_listed_warnings)
      listed += (listed.empty() ? "" : "; ") + where(t) + " (vertices " + std::to_string(f.x) + ", " +
                std::to_string(f.y) + ", " + std::to_string(f.z) + "): " + why;
    ++degenerate;
  }
  if (degenerate > 0)
    warnings.push_back(prefix + std::to_string(degenerate) + " degenerate face(s): " + listed +
                       detail::list_more(degenerate, detail::max_listed_warnings));

  // Edges: sort (undirected key, direction, triangle) and scan runs.
  struct Edge {
    std::uint64_t key;
    int triangle;
    bool forward;  // traversed from the smaller to the larger index
  };
  std::vector<Edge> edges;
  edges.reserve(size_t(nt) * 3);
  for (int t = 0; t < nt; ++t) {
    const Vec3i& f = mesh.triangles[size_t(t)];
    for (int k = 0; k < 3; ++k) {
      const int a = f[k], b = f[(k + 1) % 3];
      if (a == b) continue;
      const std::uint64_t lo = std::uint64_t(std::min(a, b)), hi = std::uint64_t(std::max(a, b));
      edges.push_back({(lo << 32) | hi, t, a < b});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const Edge& x, const Edge& y) {
    return x.key != y.key ? x.key < y.key : x.triangle < y.triangle;
  });
  long non_manifold = 0, boundary = 0, flipped = 0;
  std::string non_manifold_list, boundary_list, flipped_list;
  const auto edge_name = [](std::uint64_t key) {
    return "edge (" + std::to_string(key >> 32) + ", " + std::to_string(key & 0xffffffffu) + ")";
  };
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j].key == edges[i].key) ++j;
    const size_t count = j - i;
    if (count > 2) {
      if (non_manifold < detail::max_listed_warnings) {
        std::string faces;
        for (size_t k = i; k < j && k < i + 4; ++k) faces += (k == i ? "" : ", ") + where(edges[k].triangle);
        if (count > 4) faces += ", ...";
        non_manifold_list += (non_manifold_list.empty() ? "" : "; ") + edge_name(edges[i].key) +
                             " is shared by " + std::to_string(count) + " faces: " + faces;
      }
      ++non_manifold;
    } else if (count == 1) {
      if (boundary < detail::max_listed_warnings)
        boundary_list += (boundary_list.empty() ? "" : "; ") + edge_name(edges[i].key) + " of " +
                         where(edges[i].triangle);
      ++boundary;
    } else if (edges[i].forward == edges[i + 1].forward) {
      if (flipped < detail::max_listed_warnings)
        flipped_list += (flipped_list.empty() ? "" : "; ") + edge_name(edges[i].key) + " between " +
                        where(edges[i].triangle) + " and " + where(edges[i + 1].triangle);
      ++flipped;
    }
    i = j;
  }
  if (non_manifold > 0)
    warnings.push_back(prefix + std::to_string(non_manifold) + " non-manifold edge(s): " + non_manifold_list +
                       detail::list_more(non_manifold, detail::max_listed_warnings));
  if (boundary > 0)
    warnings.push_back(prefix + std::to_string(boundary) + " boundary edge(s), the mesh is not closed: " +
                       boundary_list + detail::list_more(boundary, detail::max_listed_warnings));
  if (flipped > 0)
    warnings.push_back(prefix + std::to_string(flipped) +
                       " edge(s) whose two faces have opposite orientation: " + flipped_list +
                       detail::list_more(flipped, detail::max_listed_warnings));
  return warnings;
}

// Total surface area.
inline double surface_area(const Mesh& mesh) {
  double area = 0.0;
  for (const auto& f : mesh.triangles) {
    const Vec3d a(mesh.positions[size_t(f.x)]), b(mesh.positions[size_t(f.y)]), c(mesh.positions[size_t(f.z)]);
    area += 0.5 * glm::length(glm::cross(b - a, c - a));
  }
  return area;
}

}  // namespace difftrans::io
