// Portable triangle BVH: built on the host (binned SAH), traversed by one
// DT_HOST_DEVICE function on the host and in CUDA kernels. Answers the same
// closest-hit query as EmbreeScene (same RayHit, same barycentrics), so the
// generic tracer takes either; the ray/triangle test is watertight.
//
// Length: the builder, the flattened node layout and the traversal depend on
// each other's invariants (child order, leaf ranges, the watertight test's
// precomputed shear), so they stay in one file.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "difftrans/accel/ray_hit.hpp"
#include "difftrans/core/platform.hpp"
#include "difftrans/core/vec.hpp"

namespace difftrans::accel {

// The BVH answers with accel::RayHit (accel/ray_hit.hpp), like Embree.
using BvhHit = RayHit;

// One node, 32 bytes, depth-first: an inner node's first child directly
// follows it, its second child is at `index`. A leaf holds triangles
// [index, index + count) of the BVH's leaf order.
struct BvhNode {
  float lo[3];
  std::int32_t index;
  float hi[3];
  std::int32_t count;  // > 0: leaf; 0: inner node
  DT_HOST_DEVICE bool leaf() const { return count > 0; }
};
static_assert(sizeof(BvhNode) == 32, "BvhNode is meant to be 32 bytes");

// Deepest tree the builder makes; the traversal stack holds this many entries.
inline constexpr int bvh_max_depth = 64;

namespace detail {

// The ray, prepared once per query: the permutation and shear of the
// watertight test (Woop, Benthin, Wald 2013) and the slab test's reciprocals.
struct BvhRay {
  float o[3];
  float inv[3];  // 1 / d per axis (±inf where d is ±0 or denormal)
  int kx, ky, kz;
  float sx, sy, sz;
  bool valid;
};

DT_HOST_DEVICE DT_FORCEINLINE float bvh_abs(float x) { return x < 0.0f ? -x : x; }

DT_HOST_DEVICE inline BvhRay prepare_ray(const Vec3f& o, const Vec3f& d) {
  BvhRay r{};
  const float dv[3] = {d.x, d.y, d.z};
  int kz = 0;
  if (bvh_abs(dv[1]) > bvh_abs(dv[kz])) kz = 1;
  if (bvh_abs(dv[2]) > bvh_abs(dv[kz])) kz = 2;
  // a zero, NaN or infinite direction, or a non-finite origin, hits nothing
  const float big = 3.0e38f;
  r.valid = bvh_abs(dv[kz]) > 0.0f && bvh_abs(dv[kz]) <= big;
  for (int k = 0; k < 3; ++k) {
    r.o[k] = o[k];
    r.valid = r.valid && bvh_abs(o[k]) <= big && bvh_abs(dv[k]) <= big;
    r.inv[k] = 1.0f / dv[k];  // ±inf for a zero component: see slab_test
  }
  if (!r.valid) return r;
  int kx = kz + 1 == 3 ? 0 : kz + 1;
  int ky = kx + 1 == 3 ? 0 : kx + 1;
  if (dv[kz] < 0.0f) {  // keep the winding (sign of the edge functions) of the projection
    const int s = kx;
    kx = ky;
    ky = s;
  }
  r.kx = kx;
  r.ky = ky;
  r.kz = kz;
  r.sx = dv[kx] / dv[kz];
  r.sy = dv[ky] / dv[kz];
  r.sz = 1.0f / dv[kz];
  return r;
}

// c - a * b, rounded the same way for every vertex: on the device an explicit
// fused multiply-add (nvcc would otherwise contract as it likes), on the host
// the plain expression.
DT_HOST_DEVICE DT_FORCEINLINE float sheared(float c, float a, float b) {
#if DT_DEVICE_PASS
  return __fmaf_rn(-a, b, c);
#else
  return c - a * b;
#endif
}

// a·d − b·c with its exact sign, and exactly 0 only when the exact value is
// (float products are exact in double). Swapping the two products negates
// the result exactly, so two triangles sharing an edge agree on which side
// of it the ray passes: no ray slips between them. The device tries float
// first (uncontracted) and falls back to double on 0, as Woop et al. do.
DT_HOST_DEVICE DT_FORCEINLINE float edge_function(float a, float d, float b, float c) {
#if DT_DEVICE_PASS
  const float e = __fsub_rn(__fmul_rn(a, d), __fmul_rn(b, c));
  if (e != 0.0f) return e;
#endif
  return float(double(a) * double(d) - double(b) * double(c));
}

// 1 + 2γ(3) with γ(n) = n u / (1 − n u): the slab test's far distances are
// scaled by it so that rounding never culls a box the ray touches (pbrt).
inline constexpr float slab_far_scale = 1.0f + 2.0f * (3.0f * 0x1p-24f) / (1.0f - 3.0f * 0x1p-24f);

// Whether the ray meets the node's box within [tmin, tmax]; `entry` is where
// it enters. Conservative: rounding never culls a box the ray touches.
DT_HOST_DEVICE DT_FORCEINLINE bool slab_test(const BvhNode& n, const BvhRay& r, float tmin, float tmax,
                                             float& entry) {
  float t0 = tmin, t1 = tmax;
  for (int k = 0; k < 3; ++k) {
    const float a = (n.lo[k] - r.o[k]) * r.inv[k];
    const float b = (n.hi[k] - r.o[k]) * r.inv[k];
    // NaN is 0 · ∞: the ray runs inside the plane of one of the box's faces
    // (direction component 0), so this axis does not limit it; a parallel
    // ray strictly outside the slab gets [±∞, ±∞] and misses, as it should.
    if (!(a == a && b == b)) continue;
    const float lo = a < b ? a : b;
    const float hi = (a < b ? b : a) * slab_far_scale;
    t0 = lo > t0 ? lo : t0;
    t1 = hi < t1 ? hi : t1;
  }
  entry = t0;
  return t0 <= t1;
}

// The watertight ray/triangle test. Accepts t in [tmin, tmax]; rejects zero-
// area triangles (and rays in the triangle's plane). On a hit writes t and
// Embree's barycentrics (u of p1, v of p2).
DT_HOST_DEVICE DT_FORCEINLINE bool intersect_triangle_watertight(const float* tri, const BvhRay& r, float tmin,
                                                                 float tmax, float& t, float& u, float& v) {
  const float* p0 = tri;
  const float* p1 = tri + 3;
  const float* p2 = tri + 6;
  // vertices relative to the origin, permuted so that z is the dominant axis
  const float az = p0[r.kz] - r.o[r.kz], bz = p1[r.kz] - r.o[r.kz], cz = p2[r.kz] - r.o[r.kz];
  const float ax = sheared(p0[r.kx] - r.o[r.kx], r.sx, az), ay = sheared(p0[r.ky] - r.o[r.ky], r.sy, az);
  const float bx = sheared(p1[r.kx] - r.o[r.kx], r.sx, bz), by = sheared(p1[r.ky] - r.o[r.ky], r.sy, bz);
  const float cx = sheared(p2[r.kx] - r.o[r.kx], r.sx, cz), cy = sheared(p2[r.ky] - r.o[r.ky], r.sy, cz);
  // scaled barycentrics: the 2D edge functions (U weights p0, V p1, W p2)
  const float U = edge_function(cx, by, cy, bx);
  const float V = edge_function(ax, cy, ay, cx);
  const float W = edge_function(bx, ay, by, ax);
  if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f)) return false;
  const float det = U + V + W;
  if (det == 0.0f) return false;
  const float T = U * (r.sz * az) + V * (r.sz * bz) + W * (r.sz * cz);
  const float inv = 1.0f / det;
  const float th = T * inv;
  if (!(th >= tmin && th <= tmax)) return false;
  // zero-area triangles are never reported: after shearing, a sliver can look
  // like a proper triangle in 2D, so check the 3D edge vectors (|sin| > ~1e-6)
  const float e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  const float e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
  const float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  const float nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
  const float l1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
  const float l2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
  if (!(nn > 1e-12f * l1 * l2)) return false;
  t = th;
  u = V * inv;
  v = W * inv;
  return true;
}

}  // namespace detail

// The device-copyable view: raw pointers into arrays owned elsewhere (a Bvh
// on the host, or device buffers holding copies of them).
struct BvhView {
  const BvhNode* nodes = nullptr;
  const float* vertices = nullptr;      // 9 per triangle (p0 p1 p2), in leaf order
  const std::int32_t* prims = nullptr;  // the mesh's triangle index of each leaf slot
  std::int32_t node_count = 0;
  std::int32_t triangle_count = 0;

  // Closest hit along o + t d for t in [tnear, tfar]; a miss has prim = −1.
  DT_HOST_DEVICE BvhHit intersect(const Vec3f& o, const Vec3f& d, float tnear = 0.0f,
                                  float tfar = 3.402823466e38f) const {
    BvhHit best;
    if (node_count <= 0 || !(tnear <= tfar)) return best;
    const detail::BvhRay r = detail::prepare_ray(o, d);
    if (!r.valid) return best;
    float entry;
    if (!detail::slab_test(nodes[0], r, tnear, tfar, entry)) return best;
    float closest = tfar;
    struct Entry {
      std::int32_t node;
      float t;
    };
    Entry stack[bvh_max_depth];
    int top = 0;
    std::int32_t node = 0;
    for (;;) {
      const BvhNode& n = nodes[node];
      if (n.leaf()) {
        const std::int32_t end = n.index + n.count;
        for (std::int32_t k = n.index; k < end; ++k) {
          float t, u, v;
          if (detail::intersect_triangle_watertight(vertices + 9 * std::int64_t(k), r, tnear, closest, t, u, v) &&
              (best.prim < 0 || t < closest)) {
            closest = t;
            best.prim = prims[k];
            best.t = t;
            best.u = u;
            best.v = v;
          }
        }
      } else {
        const std::int32_t c0 = node + 1, c1 = n.index;
        float t0, t1;
        const bool h0 = detail::slab_test(nodes[c0], r, tnear, closest, t0);
        const bool h1 = detail::slab_test(nodes[c1], r, tnear, closest, t1);
        if (h0 && h1) {
          const bool first_near = t0 <= t1;
          stack[top++] = Entry{first_near ? c1 : c0, first_near ? t1 : t0};
          node = first_near ? c0 : c1;
          continue;
        }
        if (h0 || h1) {
          node = h0 ? c0 : c1;
          continue;
        }
      }
      // next pending subtree the ray can still reach before the closest hit
      bool found = false;
      while (top > 0) {
        const Entry e = stack[--top];
        if (e.t <= closest) {
          node = e.node;
          found = true;
          break;
        }
      }
      if (!found) break;
    }
    return best;
  }
};

// How a Bvh is built.
struct BvhOptions {
  int leaf_size = 4;               // split nodes with more triangles than this
  int bins = 16;                   // SAH bins per axis
  int max_sah_depth = 32;          // from this depth on, plain median splits (bounds the depth)
  float rebuild_threshold = 1.5f;  // update_positions rebuilds when refitting made the SAH cost this much worse
};

// Host owner: builds the BVH over a mesh, owns its arrays, refits or
// rebuilds when the positions change. Usable as the tracer's Accel directly
// (host), or through view() (device copies: see cuda/render.cuh).
class Bvh {
 public:
  using Options = BvhOptions;

  Bvh() = default;

  // positions: x y z per vertex; indices: three per triangle. Throws
  // std::invalid_argument naming the first bad vertex or triangle.
  Bvh(const float* positions, std::int32_t vertex_count, const std::int32_t* indices, std::int32_t triangle_count,
      const std::string& name = "mesh", Options options = Options())
      : name_(name), options_(options) {
    if (vertex_count < 0 || triangle_count < 0)
      throw std::invalid_argument(name_ + ": negative vertex or triangle count");
    if (options_.leaf_size < 1) options_.leaf_size = 1;
    if (options_.bins < 2) options_.bins = 2;
    if (options_.max_sah_depth > 32) options_.max_sah_depth = 32;
    vertex_count_ = vertex_count;
    for (std::int32_t f = 0; f < triangle_count; ++f)
      for (int k = 0; k < 3; ++k) {
        const std::int32_t i = indices[3 * std::int64_t(f) + k];
        if (i < 0 || i >= vertex_count)
          throw std::invalid_argument(name_ + ": triangle " + std::to_string(f) + " refers to vertex " +
                                      std::to_string(i) + ", but there are " + std::to_string(vertex_count) +
                                      " vertices");
      }
    indices_.assign(indices, indices + 3 * std::int64_t(triangle_count));
    build(positions);
  }

  // New positions, same topology: the boxes are refitted, and the tree is
  // rebuilt when that made it much worse (its SAH cost grew past the threshold).
  void update_positions(const float* positions) {
    refit(positions);
    if (sah_cost_ > options_.rebuild_threshold * built_cost_) rebuild(positions);
  }
  // New positions, same tree: boxes recomputed bottom-up.
  void refit(const float* positions) {
    validate_positions(positions);
    gather_vertices(positions);
    for (std::int32_t i = std::int32_t(nodes_.size()) - 1; i >= 0; --i) {
      BvhNode& n = nodes_[std::size_t(i)];
      if (n.leaf()) {
        set_empty(n);
        for (std::int32_t k = n.index; k < n.index + n.count; ++k)
          for (int j = 0; j < 3; ++j) grow(n, &vertices_[9 * std::size_t(k) + 3 * j]);
      } else {
        const BvhNode &a = nodes_[std::size_t(i) + 1], &b = nodes_[std::size_t(n.index)];
        for (int k = 0; k < 3; ++k) {
          n.lo[k] = std::min(a.lo[k], b.lo[k]);
          n.hi[k] = std::max(a.hi[k], b.hi[k]);
        }
      }
    }
    sah_cost_ = compute_sah_cost();
  }
  // New positions, new tree.
  void rebuild(const float* positions) { build(positions); }

  // Closest hit (host), as BvhView::intersect.
  BvhHit intersect(const Vec3f& o, const Vec3f& d, float tnear = 0.0f,
                   float tfar = std::numeric_limits<float>::infinity()) const {
    return view().intersect(o, d, tnear, tfar);
  }

  BvhView view() const {
    BvhView v;
    v.nodes = nodes_.data();
    v.vertices = vertices_.data();
    v.prims = prims_.data();
    v.node_count = std::int32_t(nodes_.size());
    v.triangle_count = triangle_count();
    return v;
  }

  std::int32_t vertex_count() const { return vertex_count_; }
  std::int32_t triangle_count() const { return std::int32_t(indices_.size() / 3); }
  const std::vector<BvhNode>& nodes() const { return nodes_; }
  const std::vector<float>& vertices() const { return vertices_; }
  const std::vector<std::int32_t>& prims() const { return prims_; }
  int depth() const { return depth_; }
  // Expected cost of a random ray (SAH, traversal step = 1, triangle test = 1),
  // now and right after the last build.
  double sah_cost() const { return sah_cost_; }
  double built_sah_cost() const { return built_cost_; }

 private:
  struct Box {
    float lo[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                   std::numeric_limits<float>::infinity()};
    float hi[3] = {-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                   -std::numeric_limits<float>::infinity()};
    void grow(const float* p) {
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], p[k]);
        hi[k] = std::max(hi[k], p[k]);
      }
    }
    void grow(const Box& b) {
      grow(b.lo);
      grow(b.hi);
    }
    bool empty() const { return lo[0] > hi[0]; }
    double area() const {
      if (empty()) return 0.0;
      const double x = double(hi[0]) - lo[0], y = double(hi[1]) - lo[1], z = double(hi[2]) - lo[2];
      return 2.0 * (x * y + y * z + z * x);
    }
  };

  static void set_empty(BvhNode& n) {
    for (int k = 0; k < 3; ++k) {
      n.lo[k] = std::numeric_limits<float>::infinity();
      n.hi[k] = -std::numeric_limits<float>::infinity();
    }
  }
  static void grow(BvhNode& n, const float* p) {
    for (int k = 0; k < 3; ++k) {
      n.lo[k] = std::min(n.lo[k], p[k]);
      n.hi[k] = std::max(n.hi[k], p[k]);
    }
  }

  void validate_positions(const float* positions) const {
    for (std::int32_t i = 0; i < vertex_count_; ++i)
      for (int k = 0; k < 3; ++k)
        if (!std::isfinite(positions[3 * std::int64_t(i) + k]))
          throw std::invalid_argument(name_ + ": vertex " + std::to_string(i) + " has a non-finite coordinate (" +
                                      std::to_string(positions[3 * std::int64_t(i) + k]) + ")");
  }

  void gather_vertices(const float* positions) {
    vertices_.resize(9 * prims_.size());
    for (std::size_t s = 0; s < prims_.size(); ++s)
      for (int j = 0; j < 3; ++j) {
        const std::int32_t vi = indices_[3 * std::size_t(prims_[s]) + std::size_t(j)];
        for (int k = 0; k < 3; ++k) vertices_[9 * s + 3 * std::size_t(j) + std::size_t(k)] = positions[3 * std::int64_t(vi) + k];
      }
  }

  void build(const float* positions) {
    validate_positions(positions);
    const std::int32_t nt = triangle_count();
    nodes_.clear();
    depth_ = 0;
    boxes_.assign(std::size_t(nt), Box());
    centroids_.assign(3 * std::size_t(nt), 0.0f);
    prims_.resize(std::size_t(nt));
    for (std::int32_t f = 0; f < nt; ++f) {
      prims_[std::size_t(f)] = f;
      Box& b = boxes_[std::size_t(f)];
      for (int j = 0; j < 3; ++j) b.grow(positions + 3 * std::int64_t(indices_[3 * std::size_t(f) + std::size_t(j)]));
      for (int k = 0; k < 3; ++k) centroids_[3 * std::size_t(f) + std::size_t(k)] = 0.5f * (b.lo[k] + b.hi[k]);
    }
    if (nt > 0) {
      nodes_.reserve(2 * std::size_t(nt) / std::size_t(options_.leaf_size) + 1);
      build_node(0, nt, 1);
    }
    boxes_.clear();
    boxes_.shrink_to_fit();
    centroids_.clear();
    centroids_.shrink_to_fit();
    gather_vertices(positions);
    sah_cost_ = built_cost_ = compute_sah_cost();
  }

  // Builds the subtree over prims_[begin, end) at `depth`; returns its node index.
  std::int32_t build_node(std::int32_t begin, std::int32_t end, int depth) {
    depth_ = std::max(depth_, depth);
    const std::int32_t id = std::int32_t(nodes_.size());
    nodes_.emplace_back();
    Box bounds, cbounds;
    for (std::int32_t i = begin; i < end; ++i) {
      bounds.grow(boxes_[std::size_t(prims_[std::size_t(i)])]);
      cbounds.grow(&centroids_[3 * std::size_t(prims_[std::size_t(i)])]);
    }
    const std::int32_t count = end - begin;
    const auto make_leaf = [&] {
      BvhNode& n = nodes_[std::size_t(id)];
      for (int k = 0; k < 3; ++k) {
        n.lo[k] = bounds.lo[k];
        n.hi[k] = bounds.hi[k];
      }
      n.index = begin;
      n.count = count;
    };
    if (count <= options_.leaf_size) {
      make_leaf();
      return id;
    }
    std::int32_t mid = -1;
    if (depth < options_.max_sah_depth) mid = sah_split(begin, end, bounds, cbounds);
    if (mid <= begin || mid >= end) {
      // median split along the widest centroid axis (also for equal centroids)
      int axis = 0;
      for (int k = 1; k < 3; ++k)
        if (cbounds.hi[k] - cbounds.lo[k] > cbounds.hi[axis] - cbounds.lo[axis]) axis = k;
      mid = begin + count / 2;
      std::nth_element(prims_.begin() + begin, prims_.begin() + mid, prims_.begin() + end,
                       [&](std::int32_t a, std::int32_t b) {
                         const float ca = centroids_[3 * std::size_t(a) + std::size_t(axis)];
                         const float cb = centroids_[3 * std::size_t(b) + std::size_t(axis)];
                         return ca < cb || (ca == cb && a < b);
                       });
    }
    build_node(begin, mid, depth + 1);
    const std::int32_t second = build_node(mid, end, depth + 1);
    BvhNode& n = nodes_[std::size_t(id)];
    for (int k = 0; k < 3; ++k) {
      n.lo[k] = bounds.lo[k];
      n.hi[k] = bounds.hi[k];
    }
    n.index = second;
    n.count = 0;
    return id;
  }

  // Binned SAH over the three axes: partitions prims_[begin, end) and
  // returns the split position, or −1 when no split separates the centroids.
  std::int32_t sah_split(std::int32_t begin, std::int32_t end, const Box& bounds, const Box& cbounds) {
    const int nb = options_.bins;
    struct Bin {
      Box box;
      std::int32_t count = 0;
    };
    std::vector<Bin> bins(static_cast<std::size_t>(nb));
    std::vector<double> right_area(static_cast<std::size_t>(nb));
    std::vector<std::int32_t> right_count(static_cast<std::size_t>(nb));
    double best_cost = std::numeric_limits<double>::infinity();
    int best_axis = -1, best_bin = -1;
    for (int axis = 0; axis < 3; ++axis) {
      const float lo = cbounds.lo[axis], extent = cbounds.hi[axis] - cbounds.lo[axis];
      if (!(extent > 0.0f)) continue;
      const float scale = float(nb) / extent;
      for (Bin& b : bins) b = Bin();
      for (std::int32_t i = begin; i < end; ++i) {
        const std::int32_t p = prims_[std::size_t(i)];
        const int b = bin_of(centroids_[3 * std::size_t(p) + std::size_t(axis)], lo, scale, nb);
        bins[std::size_t(b)].box.grow(boxes_[std::size_t(p)]);
        ++bins[std::size_t(b)].count;
      }
      Box acc;
      std::int32_t cnt = 0;
      for (int b = nb - 1; b > 0; --b) {
        acc.grow(bins[std::size_t(b)].box);
        cnt += bins[std::size_t(b)].count;
        right_area[std::size_t(b)] = acc.area();
        right_count[std::size_t(b)] = cnt;
      }
      Box left;
      std::int32_t lcnt = 0;
      for (int b = 1; b < nb; ++b) {  // split between bin b − 1 and bin b
        left.grow(bins[std::size_t(b) - 1].box);
        lcnt += bins[std::size_t(b) - 1].count;
        if (lcnt == 0 || right_count[std::size_t(b)] == 0) continue;
        const double cost = left.area() * lcnt + right_area[std::size_t(b)] * right_count[std::size_t(b)];
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = axis;
          best_bin = b;
        }
      }
    }
    (void)bounds;
    if (best_axis < 0) return -1;
    const float lo = cbounds.lo[best_axis];
    const float scale = float(nb) / (cbounds.hi[best_axis] - cbounds.lo[best_axis]);
    const auto it = std::partition(prims_.begin() + begin, prims_.begin() + end, [&](std::int32_t p) {
      return bin_of(centroids_[3 * std::size_t(p) + std::size_t(best_axis)], lo, scale, nb) < best_bin;
    });
    return std::int32_t(it - prims_.begin());
  }

  static int bin_of(float c, float lo, float scale, int nb) {
    const int b = int((c - lo) * scale);
    return b < 0 ? 0 : (b >= nb ? nb - 1 : b);
  }

  static double node_area(const BvhNode& n) {
    if (n.lo[0] > n.hi[0]) return 0.0;
    const double x = double(n.hi[0]) - n.lo[0], y = double(n.hi[1]) - n.lo[1], z = double(n.hi[2]) - n.lo[2];
    return 2.0 * (x * y + y * z + z * x);
  }

  double compute_sah_cost() const {
    if (nodes_.empty()) return 0.0;
    const double root = node_area(nodes_[0]);
    if (!(root > 0.0)) return double(triangle_count());
    double cost = 0.0;
    for (const BvhNode& n : nodes_) cost += node_area(n) / root * (n.leaf() ? double(n.count) : 1.0);
    return cost;
  }

  std::string name_ = "mesh";
  Options options_;
  std::int32_t vertex_count_ = 0;
  std::vector<std::int32_t> indices_;  // the mesh's triangles, 3 each
  std::vector<BvhNode> nodes_;
  std::vector<float> vertices_;        // 9 per leaf slot
  std::vector<std::int32_t> prims_;    // mesh triangle of each leaf slot
  std::vector<Box> boxes_;             // build scratch
  std::vector<float> centroids_;       // build scratch
  int depth_ = 0;
  double sah_cost_ = 0.0, built_cost_ = 0.0;
};

}  // namespace difftrans::accel
