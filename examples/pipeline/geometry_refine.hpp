// Stage 1, second half: the FlexiCubes mesh remeshed to an even edge length
// (Botsch–Kobbelt, geometry/remesh.hpp) and its vertices refined with the
// large-steps optimizer (optim/large_steps.hpp) on mask L1 + edge-normal
// smoothness. Stage 2's mask step on the vertices reuses the same loss.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <functional>
#include <numeric>
#include <random>
#include <vector>

#include "difftrans/geometry/curvature_sizing.hpp"
#include "difftrans/geometry/remesh.hpp"
#include "difftrans/geometry/topology.hpp"
#include "difftrans/losses/mask.hpp"
#include "difftrans/losses/mesh_terms.hpp"
#include "difftrans/optim/large_steps.hpp"
#include "difftrans/render/silhouette.hpp"
#include "pipeline/geometry.hpp"

namespace difftrans::pipeline {

// Mean mask L1 of a float mesh over all the views (0 for no views).
inline double stage1_mask_error(const std::vector<float>& positions, const std::vector<std::int32_t>& triangles,
                                const std::vector<Stage1View>& views) {
  if (views.empty()) return 0.0;
  const scene::TriangleMesh m(positions, triangles);
  const geometry::TriangleNeighbors nb = geometry::TriangleNeighbors::build(m);
  double sum = 0.0;
  for (const Stage1View& v : views) sum += losses::mask_l1(render::silhouette_mask<float>(m, v.camera, &nb), v.target.data());
  return sum / double(views.size());
}

// ------------------------------------------------------------------ refinement

struct Stage1RefineStats {
  int iteration = 0;
  double loss = 0.0, mask = 0.0, edge_normal = 0.0;
  double seconds = 0.0;
};

struct Stage1RefineResult {
  std::vector<float> positions;
  std::vector<std::int32_t> triangles;
  std::vector<double> loss, mask;  // per refinement iteration
  float target_length = 0.0f;
  // curvature-adaptive remeshing (remesh_max_length > 1): the targets asked
  // of the input's vertices, their quantiles 0, 0.5 and 1 (0 when uniform)
  float sizing_min = 0.0f, sizing_median = 0.0f, sizing_max = 0.0f;
  RemeshStats remesh_stats;
  bool remeshed = false;           // false when the input was not a manifold the remesher accepts
  double remesh_seconds = 0.0, refine_seconds = 0.0;
};

// Mask L1 (a batch of views) + edge-normal smoothness of a float mesh, and
// the gradient w.r.t. its positions (3 per vertex) written to `grad`.
inline Stage1RefineStats stage1_refine_loss(const scene::TriangleMesh& m, const geometry::TriangleNeighbors& nb,
                                            const MeshAdjacency& adj, const std::vector<Stage1View>& views,
                                            const std::vector<int>& picked, float edge_weight, std::vector<float>& grad,
                                            losses::EdgeNormalForm edge_form = losses::EdgeNormalForm::squared) {
  Stage1RefineStats st;
  grad.assign(m.positions.size(), 0.0f);
  const float per_view = 1.0f / float(std::max<std::size_t>(1, picked.size()));
  for (int vi : picked) {
    const Stage1View& view = views[std::size_t(vi)];
    const render::SilhouetteFrame f = render::prepare_silhouette(m, nb, view.camera);
    const std::vector<float> mask = render::antialiased_mask<float>(f, m, view.camera);
    std::vector<float> adjoint(mask.size());
    st.mask += losses::mask_l1(mask, view.target.data(), adjoint.data()) * per_view;
    for (float& a : adjoint) a *= per_view;
    render::silhouette_backward(f, m, view.camera, adjoint.data(), grad.data());
  }
  if (edge_weight != 0.0f) {
    using V = ad::Var<float>;
    const std::int32_t nv = m.num_vertices();
    ad::Tape<float> tape(std::int32_t(std::min<std::int64_t>(1ll << 30, 64 * std::int64_t(m.num_triangles()) + 16 * nv + 1024)));
    std::vector<Vec3<V>> x(static_cast<std::size_t>(nv));
    for (std::int32_t v = 0; v < nv; ++v)
      for (int c = 0; c < 3; ++c) x[std::size_t(v)][c] = tape.variable(m.positions[std::size_t(3 * v + c)]);
    const V e = edge_normal_loss(x, m.triangles, adj, Reduction::mean, edge_form);
    if (!tape.overflowed()) {
      tape.backward(e);
      for (std::int32_t v = 0; v < nv; ++v)
        for (int c = 0; c < 3; ++c) grad[std::size_t(3 * v + c)] += edge_weight * tape.adjoint(x[std::size_t(v)][c]);
      st.edge_normal = e.value;
    }
  }
  st.loss = st.mask + edge_weight * st.edge_normal;
  return st;
}

// Remesh to the target edge length, then refine the vertex positions with the
// large-steps optimizer (u = (I + λL) x, AdamUniform on u) for
// config.refine_iterations iterations. `on_step` (optional) sees each iteration.
inline Stage1RefineResult stage1_refine(const std::vector<float>& positions, const std::vector<std::int32_t>& triangles,
                                        const std::vector<Stage1View>& views, const Stage1Config& config,
                                        const std::function<void(const Stage1RefineStats&)>& on_step = {}) {
  using clock = std::chrono::steady_clock;
  Stage1RefineResult out;
  const auto t0 = clock::now();
  RemeshOptions ro;
  const Vec3f size = config.box_hi - config.box_lo;
  ro.target_length = config.remesh_edge_length > 0.0f
                         ? config.remesh_edge_length
                         : std::max(size.x, std::max(size.y, size.z)) / float(std::max(2, config.grid_resolution));
  ro.iterations = config.remesh_iterations;
  CurvatureSizingResult sizing;
  if (config.remesh_max_length > 1.0f) {
    CurvatureSizing cs;
    cs.min_length = ro.target_length;
    cs.max_length = config.remesh_max_length * ro.target_length;
    cs.tolerance = config.remesh_tolerance * ro.target_length;
    sizing = curvature_sizing(positions, triangles, cs);
    ro.sizing = &sizing.length;
    if (!sizing.length.empty()) {
      std::vector<float> sorted = sizing.length;
      std::sort(sorted.begin(), sorted.end());
      out.sizing_min = sorted.front();
      out.sizing_median = sorted[sorted.size() / 2];
      out.sizing_max = sorted.back();
    }
  }
  RemeshResult rr = remesh(positions, triangles, ro);
  out.target_length = ro.target_length;
  if (rr.report.ok() && !rr.triangles.empty()) {
    out.positions = std::move(rr.positions);
    out.triangles = std::move(rr.triangles);
    out.remesh_stats = rr.stats;
    out.remeshed = true;
  } else {
    out.positions = positions;
    out.triangles = triangles;
  }
  out.remesh_seconds = std::chrono::duration<double>(clock::now() - t0).count();
  if (out.triangles.empty() || config.refine_iterations <= 0 || views.empty()) return out;

  const auto t1 = clock::now();
  scene::TriangleMesh m(out.positions, out.triangles);
  const geometry::TriangleNeighbors nb = geometry::TriangleNeighbors::build(m);
  const MeshAdjacency adj = mesh_adjacency(m.triangles, m.num_vertices());
  optim::AdamOptions ao;
  ao.lr = config.refine_lr;
  optim::LargeStepsOptimizer opt(config.refine_lambda, ao);
  opt.reset(m.positions, m.triangles);
  std::vector<float> grad;
  for (int it = 0; it < config.refine_iterations; ++it) {
    const auto ts = clock::now();
    std::vector<int> all(views.size());
    std::iota(all.begin(), all.end(), 0);
    std::mt19937_64 rng(config.seed * 0xD1B54A32D192ED03ull + std::uint64_t(it));
    std::shuffle(all.begin(), all.end(), rng);
    all.resize(std::min<std::size_t>(all.size(), std::size_t(std::max(1, config.refine_views_per_iteration))));
    Stage1RefineStats st = stage1_refine_loss(m, nb, adj, views, all, config.refine_edge_normal, grad,
                                                  config.refine_edge_form);
    opt.step(m.positions, grad, config.refine_lr);
    st.iteration = it;
    st.seconds = std::chrono::duration<double>(clock::now() - ts).count();
    out.loss.push_back(st.loss);
    out.mask.push_back(st.mask);
    if (on_step) on_step(st);
  }
  out.positions = m.positions;
  out.refine_seconds = std::chrono::duration<double>(clock::now() - t1).count();
  return out;
}

}  // namespace difftrans::pipeline
