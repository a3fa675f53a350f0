// The reverse pass with branches as work items. The per-pixel gradient
// (PooledGradientPixel) gives each thread a whole camera ray's Fresnel tree
// on one tape, so a launch lasts as long as its deepest trees, and its tapes
// (thousands of nodes a thread) live in global memory. Here the trees of a
// wave of camera rays are first grown in plain float, one launch per depth,
// every branch stored with the indices of its children (GrowTreeStep); then
// the depths are swept back from the deepest: a thread takes one branch,
// replays its one segment and interaction (render::detail::interact, the
// tracer's own step) in Var<float> from the stored origin, direction and
// weight, seeds the light it escapes with and the children's adjoints (their
// own replay, one depth deeper, wrote them), sweeps that short tape, scatters
// the parameters' adjoints and leaves the adjoint of its own origin,
// direction and weight for its parent (ReplayBranchStep). A tape then holds
// one interaction, a few hundred nodes, and fits in the thread's own memory.
// Written once over a launch backend (cuda/render.cuh on the device,
// cuda/host_launch.hpp on host threads).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/ad/ad.hpp"
#include "difftrans/cuda/render_kernels.hpp"
#include "difftrans/cuda/wavefront.hpp"
#include "difftrans/render/pass_options.hpp"
#include "difftrans/render/tracer.hpp"

namespace difftrans::cuda {

// One branch of a grown tree: what the forward step saw, and what the
// reverse step leaves for the branch's parent.
struct TreeBranch {
  render::detail::Branch<float> branch;
  std::uint64_t ray_hash = 0;    // the camera ray's (drawn and roulette choices)
  std::int32_t pixel = 0;
  std::int32_t child[2] = {-1, -1};  // the reflected and the refracted child, or −1
  float light[3] = {0.0f, 0.0f, 0.0f};  // weight × environment when the branch escaped
  float adjoint[9] = {};         // dLoss/d(origin, direction, weight), set by its replay
};

// The arrays of one wave's trees.
struct TreeJob {
  PixelJob job;                  // job.pixel_adjoint: dLoss/dpixel; job.image: accumulated (must start at zero)
  TreeBranch* branches = nullptr;
  std::uint32_t* count = nullptr;  // branches stored; past `capacity` when the wave did not fit
  std::int64_t capacity = 0;
};

// Thread i stores the camera ray of pixel sample first + i as branch i.
struct CameraBranchStep {
  TreeJob tree;
  std::int64_t first = 0;

  DT_HOST_DEVICE void operator()(int i) const {
    const int n = tree.job.samples_per_axis;
    const std::int64_t s = first + i;
    TreeBranch t;
    t.pixel = std::int32_t(s / (n * n));
    const scene::Ray r = render::pixel_sample(tree.job.camera, n, t.pixel, int(s % (n * n)));
    t.branch = render::detail::Branch<float>{r.origin, r.direction, Vec3f(1.0f), 0, 1u};
    t.ray_hash = render::detail::choice_hash(tree.job.trace, r.origin, r.direction);
    tree.branches[i] = t;
  }
};

// Thread i takes branch first + i: its segment and interaction in float;
// its escaped light is kept, its children appended (their indices kept).
struct GrowTreeStep {
  TreeJob tree;
  std::int64_t first = 0;

  DT_HOST_DEVICE void operator()(int i) const {
    const PixelJob& job = tree.job;
    TreeBranch& t = tree.branches[first + i];
    ad::ParamReader<float> reader(job.params);
    const float eta = ad::load<float>(reader, job.scene.ior, 0);
    render::TraceStats st;
    TreeBranch children[2];
    std::uint32_t k = 0;
    Vec3f light(0.0f);
    render::detail::interact<float>(
        job.scene, job.bvh, reader, t.branch, eta, t.ray_hash, job.trace, st, render::DistantEscape{},
        [&](const Vec3f& l) { light = l; },
        [&](const render::detail::Branch<float>& b) {
          TreeBranch& c = children[k++];
          c.branch = b;
          c.ray_hash = t.ray_hash;
          c.pixel = t.pixel;
        });
    for (int c = 0; c < 3; ++c) t.light[c] = light[c];
    const std::uint32_t at = detail::reserve(tree.count, k);
    for (std::uint32_t c = 0; c < k; ++c) {
      const std::int64_t j = std::int64_t(at) + c;
      if (j >= tree.capacity) continue;  // the wave did not fit: it is grown again, smaller
      tree.branches[j] = children[c];
      t.child[children[c].branch.path & 1u] = std::int32_t(j);
    }
    if (job.counters) {
      detail::reserve(job.counters + counter_segments, 1u);
      detail::reserve(job.counters + counter_hits, std::uint32_t(st.hits));
    }
  }
};

namespace detail {

// The reverse step of branch i on `tape` and `log`: adds its light into the
// image, and, if it carries derivatives, replays its interaction in
// Var<float>, scatters the parameters' adjoints and writes the adjoint of
// its origin, direction and weight. Returns false, with nothing scattered
// or written, when the tape or the log overflowed.
DT_HOST_DEVICE inline bool replay_branch(const TreeJob& tree, std::int64_t i, ad::Tape<float>& tape,
                                         ad::LeafRecord* log, std::int32_t log_capacity, bool add_light) {
  using V = ad::Var<float>;
  const PixelJob& job = tree.job;
  TreeBranch& t = tree.branches[i];
  const int n = job.samples_per_axis;
  const float w = 1.0f / float(n * n);
  if (add_light && job.image && (t.light[0] != 0.0f || t.light[1] != 0.0f || t.light[2] != 0.0f))
    for (int c = 0; c < 3; ++c) ad::detail::atomic_add(job.image + 3 * std::int64_t(t.pixel) + c, w * t.light[c]);
  const render::detail::Branch<float>& b = t.branch;
  if (!render::detail::carries_derivatives(job.trace, b.depth, b.path)) {
    // its subtree is a constant of the pass (TraceSettings::gradient_depth, gradient_refractions)
    for (float& a : t.adjoint) a = 0.0f;
    return true;
  }
  tape.reset();
  tape.zero_on_push(true);
  ad::ParamReader<V> reader(job.params, &tape, log, log_capacity);
  const V eta = ad::load<V>(reader, job.scene.ior, 0);
  // the branch's state as leaves (the camera ray's as constants: it has no parent)
  V state[9];
  for (int k = 0; k < 9; ++k) {
    const float x = k < 3 ? b.origin[k] : k < 6 ? b.direction[k - 3] : b.weight[k - 6];
    state[k] = b.depth > 0 ? tape.variable(x) : V(x);
  }
  render::detail::Branch<V> bv{Vec3<V>(state[0], state[1], state[2]), Vec3<V>(state[3], state[4], state[5]),
                               Vec3<V>(state[6], state[7], state[8]), b.depth, b.path};
  const float* a = job.pixel_adjoint + 3 * std::int64_t(t.pixel);
  render::TraceStats st;
  render::detail::interact<V>(
      job.scene, job.bvh, reader, bv, eta, t.ray_hash, job.trace, st, render::DistantEscape{},
      [&](const Vec3<V>& light) {
        for (int c = 0; c < 3; ++c) tape.seed(light[c], w * a[c]);
      },
      [&](const render::detail::Branch<V>& next) {
        const std::int32_t j = t.child[next.path & 1u];
        if (j < 0) return;  // the float step did not make it (a choice at the last bit)
        const float* adj = tree.branches[j].adjoint;
        for (int c = 0; c < 3; ++c) {
          tape.seed(next.origin[c], adj[c]);
          tape.seed(next.direction[c], adj[3 + c]);
          tape.seed(next.weight[c], adj[6 + c]);
        }
      });
  tape.zero_on_push(false);
  if (tape.overflowed() || reader.overflowed()) return false;
  tape.propagate();
  reader.scatter();
  for (int k = 0; k < 9; ++k) t.adjoint[k] = tape.adjoint(state[k]);
  if (job.counters) counter_max(job.counters + counter_max_tape, std::uint32_t(tape.peak()));
  return true;
}

}  // namespace detail

// The reverse step of branches first + i with a tape of TapeCapacity nodes
// and LogCapacity leaves in the thread's own memory; a branch that overflows
// it is appended to `overflow_list` (counted in job.counters[counter_overflow_pixels]).
template <int TapeCapacity, int LogCapacity>
struct ReplayBranchStep {
  TreeJob tree;
  std::int64_t first = 0;
  std::int32_t* overflow_list = nullptr;

  DT_HOST_DEVICE void operator()(int i) const {
    LocalTape<TapeCapacity, LogCapacity> local;
    ad::Tape<float> tape(local.nodes, local.adjoints, TapeCapacity);
    const std::int64_t b = first + i;
    if (!detail::replay_branch(tree, b, tape, local.log, LogCapacity, true))
      detail::list_overflow(tree.job.counters, overflow_list, std::int32_t(b));
  }
};

// The reverse step again for branches that overflowed the thread's own tape,
// on tapes cut from a pool (detail::run_waves: waves that fit the memory,
// longer tapes until none overflows). Item k of a try is branch
// branch_list[k], or branch_list[item_list[k]] when an item list is given.
struct PooledReplayBranch {
  TreeJob tree;
  TapePool pool;
  std::int64_t first = 0;
  std::int64_t item_count = 0;
  const std::int32_t* branch_list = nullptr;
  const std::int32_t* item_list = nullptr;
  std::int32_t* overflow_list = nullptr;

  DT_HOST_DEVICE void operator()(int slot) const {
    const std::int64_t k = first + slot;
    if (k >= item_count) return;
    const std::int32_t item = item_list ? item_list[k] : std::int32_t(k);
    const std::int64_t s = slot;
    ad::Tape<float> tape(pool.nodes + s * pool.capacity, pool.adjoints + s * pool.capacity, pool.capacity);
    if (!detail::replay_branch(tree, branch_list[item], tape, pool.logs + s * pool.log_capacity, pool.log_capacity,
                               false) &&
        overflow_list)
      detail::list_overflow(tree.job.counters, overflow_list, item);
  }
};

// How the trees are scheduled.
struct TreeSchedule {
  std::int64_t capacity = std::int64_t(1) << 24;  // branches stored at once (TreeBranch: 120 bytes each)
  GradientSchedule redo = {1 << 13, 1 << 10, 1 << 21, std::size_t(1) << 28};  // branches that overflow the own tape
};

// What run_tree_gradient did.
struct TreeGradientRun {
  int waves = 0;                    // waves of camera rays, grown and swept back
  int regrown = 0;                  // waves grown again smaller: their trees did not fit
  int launches = 0;
  std::int64_t branches = 0;        // branches swept back (each branch once)
  std::int64_t largest_wave = 0;    // camera samples
  std::int64_t largest_tree = 0;    // branches of the largest wave
  std::int64_t redone = 0;          // branches replayed again on a pooled tape
  std::int64_t dropped = 0;         // branches that overflowed the longest tape: their gradient is lost
};

// The reverse pass over `pixels` pixels with the launch backend B (the
// detail::run_waves backend plus upload/download): adds dLoss/dparameter to
// the gradient buffers of job.params given job.pixel_adjoint; job.image, if
// set, receives the image (it must hold zeros); job.counters must point at
// the backend's counters. LocalCapacity / LocalLog: the thread's own tape.
// Throws when one camera ray's tree does not fit schedule.capacity.
template <int LocalCapacity = 512, int LocalLog = 64, class B>
TreeGradientRun run_tree_gradient(B& be, const PixelJob& job, std::int64_t pixels, const TreeSchedule& schedule) {
  TreeGradientRun run;
  const std::int64_t samples = pixels * job.samples_per_axis * job.samples_per_axis;
  const std::int64_t capacity = std::max<std::int64_t>(2, std::min(schedule.capacity, std::int64_t(1) << 31));
  auto branches = be.template make<TreeBranch>(std::size_t(capacity));
  auto count = be.template make<std::uint32_t>(1);
  auto overflow = be.template make<std::int32_t>(std::size_t(capacity));
  TreeJob tree{job, branches.data(), count.data(), capacity};
  std::int64_t wave = std::max<std::int64_t>(1, std::min(samples, capacity / 8));
  std::int64_t next = 0;
  std::vector<std::int64_t> depth_start;  // depth d: branches [depth_start[d], depth_start[d + 1])
  while (next < samples) {
    const std::int64_t m = std::min(wave, samples - next);
    be.launch(int(m), CameraBranchStep{tree, next});
    ++run.launches;
    std::uint32_t stored = std::uint32_t(m);
    be.upload(count, &stored, 1);
    depth_start.assign(1, 0);
    depth_start.push_back(m);
    bool fits = true;
    while (depth_start.back() > depth_start[depth_start.size() - 2]) {
      const std::int64_t lo = depth_start[depth_start.size() - 2], hi = depth_start.back();
      be.launch(int(hi - lo), GrowTreeStep{tree, lo});
      ++run.launches;
      be.download(&stored, count, 1);
      if (std::int64_t(stored) > capacity || std::int64_t(stored) < hi) {  // past the capacity (or wrapped)
        fits = false;
        break;
      }
      depth_start.push_back(std::int64_t(stored));
    }
    if (!fits) {
      if (m == 1)
        throw std::runtime_error("tree gradient: one camera ray's tree holds more branches than the capacity (" +
                                 std::to_string(capacity) + ")");
      wave = std::max<std::int64_t>(1, m / 2);
      ++run.regrown;
      continue;
    }
    // swept back from the deepest depth: a branch's children are done before it
    for (std::size_t d = depth_start.size() - 1; d-- > 0;) {
      const std::int64_t lo = depth_start[d], hi = depth_start[d + 1];
      if (hi <= lo) continue;
      be.set_counter(counter_overflow_pixels, 0u);
      be.launch(int(hi - lo), ReplayBranchStep<LocalCapacity, LocalLog>{tree, lo, overflow.data()});
      ++run.launches;
      std::uint32_t c[counter_count];
      be.read_counters(c);
      const std::int64_t over = c[counter_overflow_pixels];
      if (over > 0) {
        run.redone += over;
        const GradientWaves w = detail::run_waves(
            be, over, schedule.redo, false,
            [&](const TapePool& pool, std::int64_t items, const std::int32_t* list, float, std::int32_t* out, bool) {
              return PooledReplayBranch{tree, pool, 0, items, overflow.data(), list, out};
            });
        run.launches += w.waves;
        run.dropped += w.dropped_pixels;
      }
    }
    run.branches += depth_start.back();
    run.largest_wave = std::max(run.largest_wave, m);
    run.largest_tree = std::max(run.largest_tree, depth_start.back());
    ++run.waves;
    next += m;
    // twice as many camera rays next time while their trees fill under a third of the capacity
    if (std::int64_t(stored) * 3 < capacity) wave = 2 * m;
  }
  return run;
}

}  // namespace difftrans::cuda
