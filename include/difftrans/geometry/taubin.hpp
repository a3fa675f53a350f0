// Taubin's λ|μ smoothing (G. Taubin, "A signal processing approach to fair
// surface design", SIGGRAPH 1995): each pass moves every vertex a fraction λ
// of the way to the mean of its neighbours, then a fraction μ < −λ of the
// way again (away from the new mean). The pair damps the shortest
// wavelengths on the mesh (noise at the scale of one edge) and passes the
// long ones, so a closed surface does not shrink as it does under plain
// Laplacian smoothing. Uniform (umbrella) weights: the result depends on the
// connectivity alone, and a vertex on a boundary or non-manifold edge stays
// where it is.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "difftrans/geometry/topology.hpp"

namespace difftrans::geometry {

// One umbrella step in place: p_v += f · (mean of v's neighbours − p_v) for
// every interior vertex, all from the positions before the step.
inline void umbrella_step(std::vector<float>& positions, const MeshAdjacency& adj, float f) {
  const std::size_t nv = std::size_t(adj.num_vertices);
  const std::vector<float> before = positions;
  for (std::size_t v = 0; v < nv; ++v) {
    if (adj.boundary[v]) continue;
    const std::int32_t first = adj.vv_offsets[v], last = adj.vv_offsets[v + 1];
    if (last <= first) continue;  // an unused vertex
    double mean[3] = {0.0, 0.0, 0.0};
    for (std::int32_t k = first; k < last; ++k) {
      const std::size_t u = std::size_t(adj.vv_neighbors[std::size_t(k)]);
      for (std::size_t c = 0; c < 3; ++c) mean[c] += double(before[3 * u + c]);
    }
    const double n = double(last - first);
    for (std::size_t c = 0; c < 3; ++c)
      positions[3 * v + c] = float(double(before[3 * v + c]) + double(f) * (mean[c] / n - double(before[3 * v + c])));
  }
}

// `passes` Taubin passes (a λ step, then a μ step) over 3 floats per vertex.
// Taubin's usual pair: λ 0.5, μ −0.53 (pass band about 0.1 of the highest
// frequency).
inline void taubin_smooth(std::vector<float>& positions, const std::vector<std::int32_t>& triangles, int passes,
                          float lambda = 0.5f, float mu = -0.53f) {
  if (positions.size() % 3 != 0) throw std::invalid_argument("taubin_smooth: positions are not 3 floats per vertex");
  if (!(lambda > 0.0f) || !(mu < -lambda))
    throw std::invalid_argument("taubin_smooth: needs lambda > 0 and mu < -lambda");
  if (passes <= 0 || positions.empty()) return;
  const MeshAdjacency adj = mesh_adjacency(triangles, std::int32_t(positions.size() / 3));
  for (int p = 0; p < passes; ++p) {
    umbrella_step(positions, adj, lambda);
    umbrella_step(positions, adj, mu);
  }
}

}  // namespace difftrans::geometry
