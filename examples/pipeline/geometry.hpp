// Stage 1 of DiffTrans: the object's shape from its masks alone. A FlexiCubes
// grid is optimized against anti-aliased silhouettes (mask L1) with the
// regularizers and the three-phase schedule of the paper; the extracted mesh
// is then remeshed and refined (geometry_refine.hpp).
//
// Length: the FlexiCubes fit is one class (Stage1FlexiCubes) whose schedule,
// tape growth, visual-hull start, carving and checkpoint all read and write
// the same grid state; split apart, each piece would reach into the others.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "difftrans/ad/params.hpp"
#include "difftrans/ad/tape.hpp"
#include "difftrans/geometry/flexicubes.hpp"
#include "difftrans/geometry/remesh.hpp"
#include "difftrans/geometry/topology.hpp"
#include "difftrans/io/checkpoint.hpp"
#include "difftrans/losses/flexicubes_terms.hpp"
#include "difftrans/losses/mask.hpp"
#include "difftrans/losses/mesh_terms.hpp"
#include "difftrans/losses/screen_smoothness.hpp"
#include "difftrans/optim/adam.hpp"
#include "difftrans/optim/large_steps.hpp"
#include "difftrans/render/silhouette.hpp"
#include "difftrans/scene/camera.hpp"
#include "difftrans/scene/mesh.hpp"
#include "pipeline/config.hpp"

namespace difftrans::losses {
inline const std::array<const char*, 2>& enum_names(EdgeNormalForm) {
  static const std::array<const char*, 2> names{"squared", "linear"};
  return names;
}
}  // namespace difftrans::losses

namespace difftrans::pipeline {

// the parts stage 1 assembles
using namespace difftrans::geometry;
using namespace difftrans::losses;

// One training view: its camera and the target mask (width·height values in
// [0, 1], row 0 at the top, as the rasterizer stores pixels).
struct Stage1View {
  scene::Camera camera;
  std::vector<float> target;
};

// The smoothness term of the FlexiCubes phase: the screen-space term of the
// paper (|∇d| + |∇n| + |∇²n| over the rendered depth / normal maps) or, where
// that is too slow, edge-normal smoothness (1 − n_i·n_j)² on the mesh.
enum class Stage1Smoothness : int { screen_space, edge_normal, none };
inline const std::array<const char*, 3>& enum_names(Stage1Smoothness) {
  static const std::array<const char*, 3> names{"screen", "edge", "none"};
  return names;
}

// The SDF the FlexiCubes grid starts from: the visual hull of the masks, or
// the paper's sphere.
enum class Stage1Init : int { hull, sphere };
inline const std::array<const char*, 2>& enum_names(Stage1Init) {
  static const std::array<const char*, 2> names{"hull", "sphere"};
  return names;
}

// Loss weights. The mask L1 is the mean over a view's pixels, averaged over
// the views of a batch; every other term as its function in difftrans/losses/
// computes it.
struct Stage1Weights {
  float mask = 1.0f;
  float dilation = 0.1f;         // mean SDF (tape-free), in the dilation phases
  float smoothness = 5e-4f;      // screen-space or edge-normal, in the smoothness phases (0.02 visibly hurt the mask fit)
  float bce = 0.01f;             // BCE-with-logits on sign-changing grid edges
  float area = 0.1f;             // mean face area
  float dev = 0.1f;              // FlexiCubes' L_dev
  float developability = 0.01f;  // Stein et al. 2018, late only
  float weight_l1 = 1e-3f;       // L1 on the raw FlexiCubes weights (tape-free)

  template <class Self, class Visit>
  static void fields(Self& w, Visit&& v) {
    v(Field{"mask", "", "mask L1"}, w.mask);
    v(Field{"dilation", "", "SDF dilation"}, w.dilation);
    v(Field{"smoothness", "", "screen-space or edge-normal smoothness"}, w.smoothness);
    v(Field{"bce", "", "BCE on sign-changing grid edges"}, w.bce);
    v(Field{"area", "", "mean face area"}, w.area);
    v(Field{"dev", "", "FlexiCubes' L_dev"}, w.dev);
    v(Field{"developability", "", "developability"}, w.developability);
    v(Field{"weight_l1", "", "L1 on the FlexiCubes weights"}, w.weight_l1);
  }
};

struct Stage1Config {
  // grid
  int grid_resolution = 64;     // cubes per axis (32 in tests)
  Vec3f box_lo{-0.6f}, box_hi{0.6f};  // the object's box: scene.json's aabb, or the unit box with a margin
  float box_margin = 0.1f;      // the margin around the unit box when the scene gives no box (stage1_unit_box)
  Stage1Init init = Stage1Init::hull;
  float init_radius = 0.0f;     // initial sphere's radius; <= 0: 0.35 of the box's smallest side
  // schedule (the paper: 1000 iterations, mask only for 100, then dilation /
  // smoothness alternating every 50, developability late)
  int iterations = 1000;
  int mask_only_iterations = 100;
  int alternate_period = 50;     // first period after mask-only: dilation, then smoothness, ...
  int developability_start = 800;
  float lr = 0.01f;              // lr0 · 10^(−lr_decay · i)
  float lr_decay = 0.0002f;
  // Adam's ε. Adam scales every entry's step to about lr whatever its
  // gradient's size, so a grid vertex that only a regularizer reaches moves as
  // fast as one on the silhouette; a larger ε (comparable to the mask
  // gradients) makes such small gradients take proportionally small steps.
  float adam_eps = 1e-8f;
  int views_per_iteration = 8;   // the batch of training views per iteration
  Stage1Smoothness smoothness = Stage1Smoothness::screen_space;
  float dilation_band = 0.0f;    // dilation acts on grid vertices within this many cells of a sign change (see below)
  // Carving (not in the paper): a grid vertex that some view sees on a
  // background pixel whose neighbours within `carve_margin` pixels are also
  // background lies outside the object, whatever the losses say; after every
  // step its SDF is kept positive. Holes the masks see through then stay open
  // under dilation, and nothing grows where a mask says empty. < 0: off.
  // Margin 0 (a pixel centre's ray misses the object) keeps gaps of about a
  // pixel open: on monkey-bands (quick) margin 1 let the raised arm fuse with
  // the head (genus 1), margin 0 kept it apart (genus 0, CD 4.2e-5 -> 2.6e-5).
  int carve_margin = 0;
  Stage1Weights weights;
  std::uint64_t seed = 1;        // the views of iteration i are drawn from seed + i (reproducible across resume)
  // refinement
  float remesh_edge_length = 0.0f;  // <= 0: one grid cell (the box's longest side / resolution)
  int remesh_iterations = 5;
  // Curvature-adaptive remeshing (geometry::curvature_sizing): edges up to
  // remesh_max_length × the edge length above where the surface is flat
  // enough that a chord strays at most remesh_tolerance × the edge length
  // from it; 1: every edge the same length.
  float remesh_max_length = 1.0f;
  float remesh_tolerance = 0.05f;
  int refine_iterations = 1000;
  int refine_views_per_iteration = 8;
  float refine_lr = 3e-3f;          // AdamUniform on u = (I + λL) x
  double refine_lambda = 19.0;
  float refine_edge_normal = 1e-3f;  // weight of the edge-normal term (mean over interior edges; its form below)
  losses::EdgeNormalForm refine_edge_form = losses::EdgeNormalForm::squared;
  // evaluation and pictures
  std::uint64_t metric_samples = 200000;  // points per mesh for CD / F1
  int sheet_views = 4;                    // rows of the silhouette comparison strip

  // The one list of settings (pipeline/config.hpp): options, record, log.
  template <class Self, class Visit>
  static void fields(Self& c, Visit&& v) {
    constexpr double big = 1e9;
    v(Field{"grid", "--grid", "FlexiCubes resolution (cubes per axis)", 2, 1024}, c.grid_resolution);
    v(Field{"box_lo", "", "the grid's box, low corner"}, c.box_lo);
    v(Field{"box_hi", "", "the grid's box, high corner"}, c.box_hi);
    v(Field{"box_margin", "--box-margin", "margin around the unit box when scene.json has no aabb", 0, 100}, c.box_margin);
    v(Field{"init", "--init", "initial SDF: hull (visual hull of the masks) or sphere (the paper's)"}, c.init);
    v(Field{"init_radius", "", "initial sphere's radius (<= 0: 0.35 of the box)"}, c.init_radius);
    v(Field{"iterations", "--iterations", "FlexiCubes iterations", 0, big}, c.iterations);
    v(Field{"mask_only", "", "iterations with the mask term alone (--schedule)"}, c.mask_only_iterations);
    v(Field{"period", "", "iterations per dilation / smoothness phase (--schedule)"}, c.alternate_period);
    v(Field{"developability_start", "", "first iteration of the developability term (--schedule)"},
      c.developability_start);
    v(Field{"lr", "--lr", "FlexiCubes learning rate lr0 (decays as lr0 10^(-d i), d = --lr-decay)", 0, 1e3}, c.lr);
    v(Field{"lr_decay", "--lr-decay", "d in lr0 10^(-d i)", 0, 1}, c.lr_decay);
    v(Field{"adam_eps", "--adam-eps", "Adam's epsilon for the FlexiCubes unknowns", 0, 1e3}, c.adam_eps);
    v(Field{"views_per_iteration", "--batch", "training views per FlexiCubes iteration", 1, big}, c.views_per_iteration);
    v(Field{"smoothness", "--smoothness", "smoothness term of the FlexiCubes phase: screen, edge or none"}, c.smoothness);
    v(Field{"dilation_band", "", "cells around a sign change the dilation acts on (0: all)"}, c.dilation_band);
    v(Field{"carve_margin", "--carve-margin",
            "keep outside every grid vertex a view sees on background farther than this many pixels from the mask "
            "(-1: no carving)",
            -1, 1000},
      c.carve_margin);
    v(Field{"weights", "", "loss weights (--weights NAME=VALUE,...)"}, c.weights);
    v(Field{"seed", "", "seed of the view batches"}, c.seed);
    v(Field{"remesh_edge_length", "--remesh-edge-length",
            "target edge length of the remeshing, in the scene's units (<= 0: one grid cell)", -1, 100},
      c.remesh_edge_length);
    v(Field{"remesh_iterations", "", "remeshing iterations"}, c.remesh_iterations);
    v(Field{"remesh_max_length", "--remesh-max-length",
            "curvature-adaptive remeshing: longest edge, as a multiple of the edge length (1: uniform edges)", 1, 100},
      c.remesh_max_length);
    v(Field{"remesh_tolerance", "--remesh-tolerance",
            "curvature-adaptive remeshing: how far a chord may stray from the curved surface, as a fraction of the "
            "edge length",
            0, 100},
      c.remesh_tolerance);
    v(Field{"refine_iterations", "--refine-iterations", "large-steps iterations after remeshing", 0, big},
      c.refine_iterations);
    v(Field{"refine_views_per_iteration", "--refine-batch", "training views per refinement iteration", 1, big},
      c.refine_views_per_iteration);
    v(Field{"refine_lr", "", "refinement learning rate"}, c.refine_lr);
    v(Field{"refine_lambda", "--refine-lambda", "large-steps lambda of the refinement", 0, 1e6}, c.refine_lambda);
    v(Field{"refine_edge_normal", "--refine-edge-normal", "weight of the edge-normal term in the refinement", 0, 1e6},
      c.refine_edge_normal);
    v(Field{"refine_edge_form", "--refine-edge-form",
            "the refinement's edge-normal penalty per edge: squared (1 - cos)^2 or linear 1 - cos"},
      c.refine_edge_form);
    v(Field{"metric_samples", "--metric-samples", "points per mesh for CD / F1", 1, big}, c.metric_samples);
    v(Field{"sheet_views", "", "rows of the silhouette comparison strip"}, c.sheet_views);
  }
};

// The unit box [-1/2, 1/2]³ of docs/conventions.md's normalized objects, grown by `margin` on every side.
inline void stage1_unit_box(Stage1Config& c, float margin = 0.1f) {
  c.box_lo = Vec3f(-0.5f - margin);
  c.box_hi = Vec3f(0.5f + margin);
}

// What one iteration did.
struct Stage1Stats {
  int iteration = 0;
  double loss = 0.0;        // weighted total of the terms evaluated this iteration
  double mask = 0.0;        // mean mask L1 over the batch (unweighted)
  double dilation = 0.0, smoothness = 0.0, bce = 0.0, area = 0.0, dev = 0.0, developability = 0.0, weight_l1 = 0.0;
  float lr = 0.0f;
  std::int32_t vertices = 0, triangles = 0;
  std::int64_t tape_nodes = 0;
  double seconds = 0.0;           // wall time of the iteration
  double extract_seconds = 0.0;   // extraction on the tape
  double render_seconds = 0.0;    // silhouettes, mask loss and their backward
  double backward_seconds = 0.0;  // regularizers on the tape, propagation, scatter, Adam
  const char* phase = "mask";
};

// The FlexiCubes phase: the unknowns (one flat array, five ParamSet buffers
// into it), Adam over all of them, and one optimization step at a time.
//
// Dilation: the paper's term is the mean SDF over all grid vertices. Its
// gradient is the same constant 1/n everywhere, and Adam normalizes every
// entry's step, so grid vertices far from the surface (no other gradient)
// would all move by the full learning rate each step and, within one
// 50-iteration phase, turn the whole grid inside. Here the term's gradient
// (sdf_dilation_backward) is kept only on the grid vertices within
// `dilation_band` cells of a sign-changing edge, where the other terms
// balance it; the reported value is the term over the whole grid.
class Stage1FlexiCubes {
 public:
  static constexpr int buf_sdf = 0, buf_deform = 1, buf_alpha = 2, buf_beta = 3, buf_gamma = 4;

  explicit Stage1FlexiCubes(const Stage1Config& config) : config_(config) {
    grid_.res = std::max(2, config.grid_resolution);
    grid_.lo = config.box_lo;
    grid_.hi = config.box_hi;
    const std::int64_t nv = grid_.num_vertices(), nc = grid_.num_cubes();
    const std::int64_t sizes[5] = {nv, 3 * nv, 8 * nc, 12 * nc, nc};
    std::int64_t at = 0;
    for (int b = 0; b < 5; ++b) {
      offset_[b] = at;
      size_[b] = sizes[b];
      at += sizes[b];
    }
    params_.assign(std::size_t(at), 0.0f);
    grad_.assign(std::size_t(at), 0.0f);
    optim::AdamOptions ao;
    ao.lr = config.lr;
    ao.eps = config.adam_eps;
    adam_ = optim::Adam(params_.size(), ao);
    init_sphere();
  }

  // SDF of a sphere centred in the box, s = |x − c| − r (s < 0 inside);
  // deformations and weights at raw 0 (neutral). Resets the optimizer.
  void init_sphere(float radius = 0.0f) {
    const Vec3f size = grid_.hi - grid_.lo, c = 0.5f * (grid_.lo + grid_.hi);
    if (!(radius > 0.0f)) radius = config_.init_radius > 0.0f ? config_.init_radius : 0.35f * std::min(size.x, std::min(size.y, size.z));
    std::fill(params_.begin(), params_.end(), 0.0f);
    const int V = grid_.res + 1;
    float* s = params_.data() + offset_[buf_sdf];
    for (int k = 0; k < V; ++k)
      for (int j = 0; j < V; ++j)
        for (int i = 0; i < V; ++i) s[grid_.vertex_index(i, j, k)] = glm::length(grid_.vertex_position(i, j, k) - c) - radius;
    adam_.reset(params_.size());
    iteration_ = 0;
    history_.clear();
    mask_history_.clear();
  }

  // SDF from the views' visual hull (not the paper's start, an option): a
  // grid vertex is inside when it projects into every view's mask (views
  // that do not see it do not count); s = ∓(d + 1/2) h with d the grid
  // (6-neighbour) distance to the nearest vertex on a sign-changing edge and
  // h the smallest cell side, so values grow away from the surface as a
  // distance would (small values everywhere would let every step flip signs),
  // then `smoothing` passes of 6-neighbour averaging. Unlike
  // the sphere, this opens holes the masks see through (a torus's), which
  // silhouette gradients alone cannot: they act only on the rendered
  // silhouette's outline. Resets the optimizer.
  void init_visual_hull(const std::vector<Stage1View>& views, int smoothing = 1) {
    std::fill(params_.begin(), params_.end(), 0.0f);
    const int R = grid_.res, V = R + 1;
    const float h = 0.5f * glm::length(grid_.cell());
    float* s = sdf();
    const std::vector<std::uint8_t> outside = outside_masks(views, 0);
    for (std::int32_t a = 0; a < grid_.num_vertices(); ++a) s[a] = outside[std::size_t(a)] ? h : -h;
    {  // breadth-first layers from the vertices on sign-changing edges
      const std::int32_t nv = grid_.num_vertices();
      std::vector<std::int32_t> layer(static_cast<std::size_t>(nv), -1), queue;
      const std::int32_t step[3] = {1, V, V * V};
      for (int k = 0; k < V; ++k)
        for (int j = 0; j < V; ++j)
          for (int i = 0; i < V; ++i) {
            const std::int32_t a = grid_.vertex_index(i, j, k);
            const int x[3] = {i, j, k};
            bool edge = false;
            for (int axis = 0; axis < 3 && !edge; ++axis) {
              if (x[axis] > 0 && (s[a - step[axis]] < 0.0f) != (s[a] < 0.0f)) edge = true;
              if (x[axis] < R && (s[a + step[axis]] < 0.0f) != (s[a] < 0.0f)) edge = true;
            }
            if (edge) {
              layer[std::size_t(a)] = 0;
              queue.push_back(a);
            }
          }
      for (std::size_t q = 0; q < queue.size(); ++q) {
        const std::int32_t a = queue[q];
        const int x[3] = {a % V, (a / V) % V, a / (V * V)};
        for (int axis = 0; axis < 3; ++axis)
          for (int dir = -1; dir <= 1; dir += 2) {
            const int y = x[axis] + dir;
            if (y < 0 || y > R) continue;
            const std::int32_t b = a + dir * step[axis];
            if (layer[std::size_t(b)] >= 0) continue;
            layer[std::size_t(b)] = layer[std::size_t(a)] + 1;
            queue.push_back(b);
          }
      }
      const Vec3f cell = grid_.cell();
      const float side = std::min(cell.x, std::min(cell.y, cell.z));
      for (std::int32_t a = 0; a < nv; ++a) {
        const float d = layer[std::size_t(a)] >= 0 ? float(layer[std::size_t(a)]) + 0.5f : float(R);
        s[a] = s[a] < 0.0f ? -d * side : d * side;
      }
    }
    std::vector<float> tmp(std::size_t(grid_.num_vertices()));
    for (int pass = 0; pass < smoothing; ++pass) {
      for (int k = 0; k < V; ++k)
        for (int j = 0; j < V; ++j)
          for (int i = 0; i < V; ++i) {
            const std::int32_t a = grid_.vertex_index(i, j, k);
            float sum = s[a];
            int n = 1;
            const int x[3] = {i, j, k};
            const std::int32_t step[3] = {1, V, V * V};
            for (int axis = 0; axis < 3; ++axis) {
              if (x[axis] > 0) sum += s[a - step[axis]], ++n;
              if (x[axis] < R) sum += s[a + step[axis]], ++n;
            }
            tmp[std::size_t(a)] = sum / float(n);
          }
      std::copy(tmp.begin(), tmp.end(), s);
    }
    keep_border_outside();
    adam_.reset(params_.size());
    iteration_ = 0;
    history_.clear();
    mask_history_.clear();
  }

  // Grid vertices that some view sees on a background pixel whose
  // neighbours within `margin` pixels (Chebyshev) are background too; a view
  // that does not see the vertex (behind it, outside the image) says nothing.
  std::vector<std::uint8_t> outside_masks(const std::vector<Stage1View>& views, int margin) const {
    const std::int32_t nv = grid_.num_vertices();
    std::vector<std::uint8_t> out(static_cast<std::size_t>(nv), 0);
    const int V = grid_.res + 1;
    for (const Stage1View& v : views) {
      const int W = v.camera.width, H = v.camera.height;
      // background eroded by `margin`: separable min filters of (target < 0.5)
      std::vector<std::uint8_t> bg(std::size_t(W) * std::size_t(H)), tmp(bg.size());
      for (std::size_t p = 0; p < bg.size(); ++p) bg[p] = v.target[p] < 0.5f;
      if (margin > 0) {
        for (int y = 0; y < H; ++y)
          for (int x = 0; x < W; ++x) {
            std::uint8_t m = 1;
            for (int d = -margin; d <= margin && m; ++d) m = bg[std::size_t(y) * W + std::size_t(std::clamp(x + d, 0, W - 1))];
            tmp[std::size_t(y) * W + std::size_t(x)] = m;
          }
        for (int y = 0; y < H; ++y)
          for (int x = 0; x < W; ++x) {
            std::uint8_t m = 1;
            for (int d = -margin; d <= margin && m; ++d) m = tmp[std::size_t(std::clamp(y + d, 0, H - 1)) * W + std::size_t(x)];
            bg[std::size_t(y) * W + std::size_t(x)] = m;
          }
      }
      for (int k = 0; k < V; ++k)
        for (int j = 0; j < V; ++j)
          for (int i = 0; i < V; ++i) {
            const std::int32_t a = grid_.vertex_index(i, j, k);
            if (out[std::size_t(a)]) continue;
            const scene::Projection<float> q = v.camera.project(grid_.vertex_position(i, j, k));
            if (!q.valid) continue;
            const int x = int(std::floor(q.pixel.x)), y = int(std::floor(q.pixel.y));
            if (x < 0 || y < 0 || x >= W || y >= H) continue;
            if (bg[std::size_t(y) * std::size_t(W) + std::size_t(x)]) out[std::size_t(a)] = 1;
          }
    }
    return out;
  }

  // Turns carving on for these views (config().carve_margin >= 0) and
  // applies it; call after construction, init or load.
  void set_carving(const std::vector<Stage1View>& views) {
    carved_.clear();
    if (config_.carve_margin >= 0) carved_ = outside_masks(views, config_.carve_margin);
    keep_border_outside();
  }
  // How many grid vertices carving holds outside (0 when off).
  std::int64_t carved_vertices() const {
    return std::int64_t(std::count(carved_.begin(), carved_.end(), std::uint8_t(1)));
  }

  const FlexiCubesGrid& grid() const { return grid_; }
  const Stage1Config& config() const { return config_; }
  Stage1Config& config() { return config_; }
  int iteration() const { return iteration_; }
  bool done() const { return iteration_ >= config_.iterations; }
  const std::vector<float>& parameters() const { return params_; }
  const std::vector<double>& loss_history() const { return history_; }  // total loss per finished iteration
  const std::vector<double>& mask_history() const { return mask_history_; }
  float* sdf() { return params_.data() + offset_[buf_sdf]; }
  const float* sdf() const { return params_.data() + offset_[buf_sdf]; }

  // The unknowns as extraction inputs, differentiable (buffers 0..4) or constant.
  FlexiCubesInputs inputs(bool differentiable) const {
    FlexiCubesInputs in;
    ad::ParamSource* src[5] = {&in.sdf, &in.deform, &in.alpha, &in.beta, &in.gamma};
    for (int b = 0; b < 5; ++b)
      *src[b] = ad::ParamSource{params_.data() + offset_[b], std::int32_t(size_[b]), differentiable ? b : -1};
    return in;
  }

  // The current mesh in float (two_triangles: the paper's inference split).
  FlexiCubesMesh<float> extract(QuadSplit split = QuadSplit::two_triangles) const {
    FlexiCubesOptions o;
    o.split = split;
    return flexicubes_extract<float>(grid_, inputs(false), o);
  }

  // The phase of iteration i: "mask", "dilation" or "smoothness".
  const char* phase(int i) const {
    if (i < config_.mask_only_iterations) return "mask";
    const int period = std::max(1, config_.alternate_period);
    return ((i - config_.mask_only_iterations) / period) % 2 == 0 ? "dilation" : "smoothness";
  }

  // The training views of iteration i: a reproducible draw without repetition.
  std::vector<int> batch(int i, int num_views, int count) const {
    std::vector<int> all(std::size_t(std::max(0, num_views)));
    std::iota(all.begin(), all.end(), 0);
    std::mt19937_64 rng(config_.seed * 0x9E3779B97F4A7C15ull + std::uint64_t(i));
    std::shuffle(all.begin(), all.end(), rng);
    all.resize(std::size_t(std::min(count, num_views)));
    return all;
  }

  // One iteration: extraction on the tape, silhouettes and mask L1 of a batch
  // of views, the phase's regularizers, one backward pass, Adam.
  Stage1Stats step(const std::vector<Stage1View>& views) {
    using clock = std::chrono::steady_clock;
    using V = ad::Var<float>;
    const auto t0 = clock::now();
    const int it = iteration_;
    const Stage1Weights& w = config_.weights;
    Stage1Stats st;
    st.iteration = it;
    st.phase = phase(it);
    const bool mask_only = it < config_.mask_only_iterations;
    const bool dilation_phase = std::strcmp(st.phase, "dilation") == 0;
    const bool smooth_phase = std::strcmp(st.phase, "smoothness") == 0;
    const bool late = it >= config_.developability_start && !mask_only;
    st.lr = optim::exponential_lr(config_.lr, it, config_.lr_decay);

    std::fill(grad_.begin(), grad_.end(), 0.0f);
    ad::ParamSet set;
    for (int b = 0; b < 5; ++b) {
      set.buffers[b].values = params_.data() + offset_[b];
      set.buffers[b].size = std::int32_t(size_[b]);
      set.buffers[b].gradient = grad_.data() + offset_[b];
    }
    const FlexiCubesInputs in = inputs(true);
    FlexiCubesOptions fo;  // four_triangles: γ gets gradients

    // Record extraction (and the tape's regularizers) until the tape and the
    // log are large enough; they are kept across iterations.
    for (int attempt = 0;; ++attempt) {
      if (!tape_) tape_ = std::make_unique<ad::Tape<float>>(tape_capacity_);
      if (log_.size() < std::size_t(log_capacity_)) log_.resize(std::size_t(log_capacity_));
      tape_->reset();
      ad::ParamReader<V> reader(&set, tape_.get(), log_.data(), log_capacity_);
      const auto te = clock::now();
      FlexiCubesMesh<V> mesh = flexicubes_extract<V>(grid_, in, reader, fo);
      st.extract_seconds = seconds_since(te);
      st.vertices = std::int32_t(mesh.vertices.size());
      st.triangles = mesh.num_triangles();

      // float mesh, silhouettes and mask gradient w.r.t. the vertices
      const auto tr = clock::now();
      std::vector<float> pos(3 * mesh.vertices.size());
      for (std::size_t v = 0; v < mesh.vertices.size(); ++v)
        for (int c = 0; c < 3; ++c) pos[3 * v + std::size_t(c)] = mesh.vertices[v][c].value;
      std::vector<float> gpos(pos.size(), 0.0f);
      // the terms recorded on the tape: value, weight, and where the record keeps the value
      struct TapeTerm {
        V value;
        float weight;
        double Stage1Stats::*record;
      };
      std::vector<TapeTerm> terms;
      if (!mesh.triangles.empty()) {
        const scene::TriangleMesh fm(pos, mesh.triangles);
        const geometry::TriangleNeighbors nb = geometry::TriangleNeighbors::build(fm);
        const std::vector<int> picked = batch(it, int(views.size()), config_.views_per_iteration);
        const float per_view = 1.0f / float(std::max<std::size_t>(1, picked.size()));
        std::vector<float> gsmooth;
        if (smooth_phase && config_.smoothness == Stage1Smoothness::screen_space) gsmooth.assign(pos.size(), 0.0f);
        for (int vi : picked) {
          const Stage1View& view = views[std::size_t(vi)];
          const render::SilhouetteFrame f = render::prepare_silhouette(fm, nb, view.camera);
          const std::vector<float> m = render::antialiased_mask<float>(f, fm, view.camera);
          std::vector<float> adj(m.size());
          st.mask += losses::mask_l1(m, view.target.data(), adj.data()) * per_view;
          for (float& a : adj) a *= w.mask * per_view;
          render::silhouette_backward(f, fm, view.camera, adj.data(), gpos.data());
          if (!gsmooth.empty()) st.smoothness += losses::smoothness_gradient(fm, view.camera, gsmooth.data()) * per_view;
        }
        for (std::size_t k = 0; k < gsmooth.size(); ++k) gpos[k] += w.smoothness * per_view * gsmooth[k];
        st.render_seconds = seconds_since(tr);

        // regularizers recorded on the same tape
        if (!mask_only) {
          if (w.bce != 0.0f) terms.push_back({sdf_sign_change_bce_loss<V>(grid_, in.sdf, reader), w.bce, &Stage1Stats::bce});
          if (w.area != 0.0f) terms.push_back({mean_face_area(mesh.vertices, mesh.triangles), w.area, &Stage1Stats::area});
          if (w.dev != 0.0f) terms.push_back({flexicubes_dev_loss<V>(grid_, in, reader, mesh, fo), w.dev, &Stage1Stats::dev});
          const bool edge_smooth = smooth_phase && config_.smoothness == Stage1Smoothness::edge_normal;
          if (edge_smooth || (late && w.developability != 0.0f)) {
            const MeshAdjacency adjm = mesh_adjacency(mesh.triangles, std::int32_t(mesh.vertices.size()));
            if (edge_smooth)
              terms.push_back({edge_normal_loss(mesh.vertices, mesh.triangles, adjm, Reduction::mean), w.smoothness,
                               &Stage1Stats::smoothness});
            if (late && w.developability != 0.0f)
              terms.push_back({developability_loss(mesh.vertices, mesh.triangles, adjm), w.developability,
                               &Stage1Stats::developability});
          }
        }
      }
      if (tape_->overflowed() || reader.overflowed()) {
        if (tape_->overflowed()) {
          tape_capacity_ = grow(tape_capacity_, tape_->size());
          tape_.reset();
        }
        if (reader.overflowed()) log_capacity_ = grow(log_capacity_, log_capacity_);
        if (attempt < 8) {
          st = Stage1Stats{};
          st.iteration = it;
          st.phase = phase(it);
          st.lr = optim::exponential_lr(config_.lr, it, config_.lr_decay);
          continue;
        }
        throw std::runtime_error("Stage1FlexiCubes: the tape keeps overflowing");
      }
      st.tape_nodes = tape_->size();

      const auto tb = clock::now();
      tape_->zero_adjoints();
      for (std::size_t v = 0; v < mesh.vertices.size(); ++v)
        for (int c = 0; c < 3; ++c) tape_->seed(mesh.vertices[v][c], gpos[3 * v + std::size_t(c)]);
      for (const TapeTerm& t : terms) tape_->seed(t.value, t.weight);
      tape_->propagate();
      reader.scatter();
      for (const TapeTerm& t : terms) st.*t.record = t.value.value;  // the values, for the record
      st.backward_seconds = seconds_since(tb);
      break;
    }

    // tape-free terms
    const auto tb = clock::now();
    if (dilation_phase && w.dilation != 0.0f) {
      std::vector<float> gd(std::size_t(size_[buf_sdf]), 0.0f);
      ad::ParamSet dset;
      dset.buffers[buf_sdf].gradient = gd.data();
      st.dilation = sdf_dilation_backward(grid_, in.sdf, dset, w.dilation);
      const std::vector<std::uint8_t> band = near_surface(config_.dilation_band);
      float* g = grad_.data() + offset_[buf_sdf];
      for (std::size_t v = 0; v < gd.size(); ++v)
        if (band[v]) g[v] += gd[v];
    }
    if (!mask_only && w.weight_l1 != 0.0f) st.weight_l1 = flexicubes_weight_l1_backward(in, set, w.weight_l1);
    adam_.step(params_.data(), grad_.data(), st.lr);
    keep_border_outside();
    st.backward_seconds += seconds_since(tb);

    st.loss = w.mask * st.mask + w.dilation * st.dilation + w.smoothness * st.smoothness + w.bce * st.bce +
              w.area * st.area + w.dev * st.dev + w.developability * st.developability + w.weight_l1 * st.weight_l1;
    history_.push_back(st.loss);
    mask_history_.push_back(st.mask);
    ++iteration_;
    st.seconds = seconds_since(t0);
    return st;
  }

  // Checkpoint: the grid, the unknowns, Adam's moments, the iteration and the
  // loss history (io/checkpoint.hpp: replaced whole or not at all).
  void save(const std::filesystem::path& path) const {
    io::CheckpointWriter f(path, "DTS1FC01");
    f.value(std::int32_t(grid_.res));
    for (int a = 0; a < 3; ++a) f.value(grid_.lo[a]);
    for (int a = 0; a < 3; ++a) f.value(grid_.hi[a]);
    f.value(std::int32_t(iteration_));
    f.value(std::int32_t(adam_.steps()));
    f.array(params_);
    f.array(adam_.first_moment());
    f.array(adam_.second_moment());
    f.array(history_);
    f.array(mask_history_);
    f.commit();
  }

  // Resumes from a checkpoint written by save() for the same grid (resolution
  // and box); returns false, changing nothing, when the file is absent,
  // unreadable or for another grid.
  bool load(const std::filesystem::path& path) {
    io::CheckpointReader f(path, "DTS1FC01");
    std::int32_t res = 0, it = 0, steps = 0;
    Vec3f lo(0.0f), hi(0.0f);
    f.value(res);
    for (int a = 0; a < 3; ++a) f.value(lo[a]);
    for (int a = 0; a < 3; ++a) f.value(hi[a]);
    if (!f.ok() || res != grid_.res || lo != grid_.lo || hi != grid_.hi) return false;
    optim::AdamState adam;
    std::vector<float> p;
    std::vector<double> h, mh;
    const std::uint64_t n = params_.size();
    f.value(it);
    f.value(steps);
    f.array(p, n);
    f.array(adam.g1, n);
    f.array(adam.g2, n);
    f.array(h, 1u << 24);
    f.array(mh, 1u << 24);
    if (!f.complete() || p.size() != n || adam.g1.size() != n || adam.g2.size() != n || it < 0 || steps < 0)
      return false;
    adam.steps = steps;
    params_ = std::move(p);
    adam_.restore(adam);
    iteration_ = it;
    history_ = std::move(h);
    mask_history_ = std::move(mh);
    return true;
  }

 private:
  static double seconds_since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  }
  static std::int32_t grow(std::int32_t capacity, std::int32_t used) {
    const std::int64_t want = std::max<std::int64_t>(2 * std::int64_t(capacity), 2 * std::int64_t(used));
    return std::int32_t(std::min<std::int64_t>(want, 1ll << 30));
  }

  // Grid vertices within `cells` (Chebyshev distance) of a vertex on a sign-changing edge.
  std::vector<std::uint8_t> near_surface(float cells) const {
    const int R = grid_.res, V = R + 1;
    const float* s = sdf();
    std::vector<std::uint8_t> on(std::size_t(grid_.num_vertices()), 0);
    for (int k = 0; k < V; ++k)
      for (int j = 0; j < V; ++j)
        for (int i = 0; i < V; ++i) {
          const std::int32_t a = grid_.vertex_index(i, j, k);
          const bool in_a = s[a] < 0.0f;
          if (i < R && (s[a + 1] < 0.0f) != in_a) on[std::size_t(a)] = on[std::size_t(a + 1)] = 1;
          if (j < R && (s[a + V] < 0.0f) != in_a) on[std::size_t(a)] = on[std::size_t(a + V)] = 1;
          if (k < R && (s[a + V * V] < 0.0f) != in_a) on[std::size_t(a)] = on[std::size_t(a + V * V)] = 1;
        }
    // dilate by separable max filters along the three axes
    const int r = std::max(0, int(std::ceil(cells)));
    std::vector<std::uint8_t> tmp(on.size());
    const std::int32_t step[3] = {1, V, V * V};
    for (int axis = 0; axis < 3; ++axis) {
      for (int k = 0; k < V; ++k)
        for (int j = 0; j < V; ++j)
          for (int i = 0; i < V; ++i) {
            const int x[3] = {i, j, k};
            const std::int32_t a = grid_.vertex_index(i, j, k);
            std::uint8_t m = 0;
            for (int d = -r; d <= r && !m; ++d) {
              const int y = x[axis] + d;
              if (y >= 0 && y < V) m = on[std::size_t(a + d * step[axis])];
            }
            tmp[std::size_t(a)] = m;
          }
      on.swap(tmp);
    }
    return on;
  }

  // Grid vertices on the box's faces stay outside (s > 0): the extraction
  // makes no faces there, so a negative border value would open the mesh.
  // So do the carved vertices (set_carving).
  void keep_border_outside() {
    const int R = grid_.res, V = R + 1;
    float* s = sdf();
    const float eps = 1e-3f * glm::length(grid_.cell());
    for (int k = 0; k < V; ++k)
      for (int j = 0; j < V; ++j)
        for (int i = 0; i < V; ++i)
          if (i == 0 || j == 0 || k == 0 || i == R || j == R || k == R) {
            float& v = s[grid_.vertex_index(i, j, k)];
            v = std::max(v, eps);
          }
    for (std::size_t a = 0; a < carved_.size(); ++a)
      if (carved_[a]) s[a] = std::max(s[a], eps);
  }

  Stage1Config config_;
  FlexiCubesGrid grid_;
  std::int64_t offset_[5] = {0}, size_[5] = {0};
  std::vector<float> params_, grad_;
  std::vector<std::uint8_t> carved_;  // grid vertices held outside (set_carving)
  optim::Adam adam_;
  int iteration_ = 0;
  std::vector<double> history_, mask_history_;
  std::unique_ptr<ad::Tape<float>> tape_;
  std::int32_t tape_capacity_ = 1 << 20;
  std::vector<ad::LeafRecord> log_;
  std::int32_t log_capacity_ = 1 << 18;
};

}  // namespace difftrans::pipeline
