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
  std::vector<std::vector<std::int32_t>> neighbours(nv);
  for (std::size_t f = 0; f + 2 < triangles.size(); f += 3) {
    const std::int32_t t[3] = {triangles[f], triangles[f + 1], triangles[f + 2]};
    const glm::vec3 an = glm::cross(at(std::size_t(t[1])) - at(std::size_t(t[0])), at(std::size_t(t[2])) - at(std::size_t(t[0])));
    for (int k = 0; k < 3; ++k) {
      normal[std::size_t(t[k])] += an;
      neighbours[std::size_t(t[k])].push_back(t[(k + 1) % 3]);
      neighbours[std::size_t(t[k])].push_back(t[(k + 2) % 3]);
    }
  }
  for (auto& n : neighbours) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  for (glm::vec3& n : normal) {
    const float l = glm::length(n);
    n = l > 0.0f ? n / l : glm::vec3(0.0f);
  }
  // the vertices within `rings` rings of v (v first), by breadth-first search
  const int rings = std::max(1, o.rings);
  const auto ball = [&](std::size_t v, std::vector<std::int32_t>& out, std::vector<std::int32_t>& mark,
                        std::int32_t stamp) {
    out.assign(1, std::int32_t(v));
    mark[v] = stamp;
    std::size_t begin = 0;
    for (int r = 0; r < rings; ++r) {
      const std::size_t end = out.size();
      for (std::size_t i = begin; i < end; ++i)
        for (std::int32_t w : neighbours[std::size_t(out[i])])
          if (mark[std::size_t(w)] != stamp) {
            mark[std::size_t(w)] = stamp;
            out.push_back(w);
          }
      begin = end;
    }
  };
  std::vector<glm::vec3> smooth(nv, glm::vec3(0.0f));
  CurvatureSizingResult r;
  r.curvature.assign(nv, 0.0f);
  r.length.assign(nv, o.max_length);
  const int chunks = 64;
  const std::int64_t per = std::int64_t((nv + std::size_t(chunks) - 1) / std::size_t(chunks));
  // one pass per step: the smoothed normals, then the curvature from them
  for (int pass = 0; pass < 2; ++pass)
    parallel_for(chunks, 1, [&](std::int64_t c0, std::int64_t c1, int) {
      std::vector<std::int32_t> near, mark(nv, -1);
      std::vector<float> rates;
      for (std::int64_t c = c0; c < c1; ++c)
        for (std::int64_t i = c * per; i < std::min<std::int64_t>(std::int64_t(nv), (c + 1) * per); ++i) {
          const std::size_t v = std::size_t(i);
          ball(v, near, mark, std::int32_t(i));
          if (pass == 0) {
            glm::vec3 sum(0.0f);
            for (std::int32_t w : near) sum += normal[std::size_t(w)];
            const float l = glm::length(sum);
            smooth[v] = l > 0.0f ? sum / l : glm::vec3(0.0f);
            continue;
          }
          rates.clear();
          for (std::size_t k = 1; k < near.size(); ++k) {
            const std::size_t w = std::size_t(near[k]);
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
          const float squared = kappa > 0.0f ? 6.0f * tol / kappa - 3.0f * tol * tol
                                             : std::numeric_limits<float>::infinity();
          const float l = squared > 0.0f ? std::sqrt(squared) : 0.0f;
          r.length[v] = std::clamp(l, o.min_length, std::max(o.min_length, o.max_length));
        }
    });
  return r;
}

}  // namespace difftrans::geometry
