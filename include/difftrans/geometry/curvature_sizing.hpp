// Target edge lengths that follow a surface's curvature, for the adaptive
// remeshing of remesh.hpp (RemeshOptions::sizing).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "difftrans/core/parallel.hpp"
#include "difftrans/geometry/topology.hpp"

namespace difftrans::geometry {

// How long the edges of a remeshing may be, per vertex of a triangle mesh,
// from its curvature: the longest chord that strays at most `tolerance` from a
// circle of the surface's largest curvature κ there, L = sqrt(6 tol / κ −
// 3 tol²), within [min_length, max_length]. So flat and gently curved parts
// get long edges (fewer vertices for the silhouettes and photographs to
// place, and less room for noise between them) and thin or sharply curved
// ones keep short edges.
//
// κ is measured at the scale of `rings` rings of neighbours, not of one edge:
// each vertex's normal is the mean of the area-weighted vertex normals within
// `rings` rings (averaging over an arc of a circle keeps the normal radial, so
// a cylinder's or a sphere's curvature survives it while noise at the scale
// of an edge averages out); κ at a vertex is the upper quartile of those
// normals' turning per unit distance towards the vertices up to `rings`
// rings away, which on a cylinder of radius r is 0.92 / r
// (the rate along a direction at angle θ to the circumference is cos θ / r)
// and on a sphere 1 / r, while the largest rate follows the noise (on a
// sphere of radius 0.5 with radial noise of a sixth of an edge, the quartile's
// median is 2.1 for the true 2: tests/geometry/curvature_sizing.test.cpp).
struct CurvatureSizing {
  float min_length = 0.0f;
  float max_length = 0.0f;
  float tolerance = 0.0f;
  int rings = 3;
};

struct CurvatureSizingResult {
  std::vector<float> length;     // target edge length per vertex
  std::vector<float> curvature;  // κ per vertex (1 / the scene's units)
};

inline CurvatureSizingResult curvature_sizing(const std::vector<float>& positions,
                                              const std::vector<std::int32_t>& triangles, const CurvatureSizing& o) {
  const std::size_t nv = positions.size() / 3;
  const auto at = [&](std::size_t v) { return glm::vec3(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]); };
  std::vector<glm::vec3> normal(nv, glm::vec3(0.0f));
  for (std::size_t f = 0; f + 2 < triangles.size(); f += 3) {
    const std::size_t a = std::size_t(triangles[f]), b = std::size_t(triangles[f + 1]), c = std::size_t(triangles[f + 2]);
    const glm::vec3 an = glm::cross(at(b) - at(a), at(c) - at(a));
    normal[a] += an;
    normal[b] += an;
    normal[c] += an;
  }
  for (glm::vec3& n : normal) {
    const float l = glm::length(n);
    n = l > 0.0f ? n / l : glm::vec3(0.0f);
  }
  const MeshAdjacency adj = mesh_adjacency(triangles, std::int32_t(nv));
  const int rings = std::max(1, o.rings);
  // pass 1: each vertex's ball (the vertices within `rings` rings, itself
  // first, by breadth-first search) and its mean normal
  std::vector<std::vector<std::int32_t>> ball(nv);
  std::vector<glm::vec3> smooth(nv, glm::vec3(0.0f));
  parallel_for(std::int64_t(nv), 256, [&](std::int64_t begin, std::int64_t end, int) {
    for (std::int64_t i = begin; i < end; ++i) {
      std::vector<std::int32_t>& near = ball[std::size_t(i)];
      near.assign(1, std::int32_t(i));
      for (int r = 0, from = 0; r < rings; ++r) {
        const int to = int(near.size());
        for (int k = from; k < to; ++k) {
          const std::size_t u = std::size_t(near[std::size_t(k)]);
          for (std::int32_t e = adj.vv_offsets[u]; e < adj.vv_offsets[u + 1]; ++e) {
            const std::int32_t w = adj.vv_neighbors[std::size_t(e)];
            if (std::find(near.begin(), near.end(), w) == near.end()) near.push_back(w);
          }
        }
        from = to;
      }
      glm::vec3 sum(0.0f);
      for (std::int32_t w : near) sum += normal[std::size_t(w)];
      const float l = glm::length(sum);
      smooth[std::size_t(i)] = l > 0.0f ? sum / l : glm::vec3(0.0f);
    }
  });
  // pass 2: κ from the mean normals' turning over each ball, and the length
  CurvatureSizingResult r;
  r.curvature.assign(nv, 0.0f);
  r.length.assign(nv, o.max_length);
  parallel_for(std::int64_t(nv), 256, [&](std::int64_t begin, std::int64_t end, int) {
    std::vector<float> rates;
    for (std::int64_t i = begin; i < end; ++i) {
      const std::size_t v = std::size_t(i);
      rates.clear();
      for (std::size_t k = 1; k < ball[v].size(); ++k) {
        const std::size_t w = std::size_t(ball[v][k]);
        const float d = glm::length(at(w) - at(v));
        const float c = glm::clamp(glm::dot(smooth[v], smooth[w]), -1.0f, 1.0f);
        if (d > 0.0f) rates.push_back(std::acos(c) / d);
      }
      float kappa = 0.0f;
      if (!rates.empty()) {
        const auto q = rates.begin() + std::ptrdiff_t(float(rates.size() - 1) * 0.75f);
        std::nth_element(rates.begin(), q, rates.end());
        kappa = *q;
      }
      r.curvature[v] = kappa;
      const float tol = o.tolerance;
      const float squared =
          kappa > 0.0f ? 6.0f * tol / kappa - 3.0f * tol * tol : std::numeric_limits<float>::infinity();
      r.length[v] = std::clamp(squared > 0.0f ? std::sqrt(squared) : 0.0f, o.min_length,
                               std::max(o.min_length, o.max_length));
    }
  });
  return r;
}

}  // namespace difftrans::geometry
