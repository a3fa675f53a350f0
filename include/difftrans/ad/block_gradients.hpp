// Reverse-mode gradients that come out the same bit for bit whatever the
// number of threads. A pass over `count` items (rays, pixels, silhouette
// crossings, vertices) is cut into a fixed number of blocks that does not
// depend on the threads; each block's readers scatter into the block's own
// zeroed copy of the gradient arrays (one writer per copy: a fixed order of
// additions), and reduce() adds the copies to the real arrays in block order.
// Atomic adds from whichever worker comes first, the alternative, change the
// rounding of every sum from run to run.
//
//   ad::BlockGradients blocks(set, count);
//   parallel_for(blocks.count(), 1, [&](std::int64_t b, std::int64_t e, int) {
//     for (std::int64_t k = b; k < e; ++k) {
//       ParamReader<Var<T>> reader(&blocks.set(k), ...);
//       for (std::int64_t i = blocks.begin(k); i < blocks.end(k); ++i) { ...; reader.scatter(); }
//     }
//   });
//   blocks.reduce();
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "difftrans/ad/params.hpp"

namespace difftrans::ad {

class BlockGradients {
 public:
  // Blocks of at least `min_items` items, at most `max_blocks` of them: the
  // memory is max_blocks copies of every gradient array `set` points at.
  BlockGradients(const ParamSet& set, std::int64_t count, std::int64_t max_blocks = 32, std::int64_t min_items = 16)
      : target_(set), count_(std::max<std::int64_t>(count, 0)) {
    const std::int64_t by_size = (count_ + std::max<std::int64_t>(min_items, 1) - 1) / std::max<std::int64_t>(min_items, 1);
    blocks_ = std::max<std::int64_t>(1, std::min(max_blocks, by_size));
    per_block_ = (count_ + blocks_ - 1) / blocks_;
    std::size_t total = 0;
    for (const ParamBuffer& b : target_.buffers)
      if (b.gradient && b.size > 0) total += std::size_t(b.size);
    copies_.assign(total * std::size_t(blocks_), 0.0f);
    sets_.assign(std::size_t(blocks_), target_);
    std::size_t at = 0;
    for (std::int64_t k = 0; k < blocks_; ++k)
      for (int b = 0; b < max_param_buffers; ++b) {
        ParamBuffer& buf = sets_[std::size_t(k)].buffers[b];
        if (!buf.gradient || buf.size <= 0) continue;
        buf.gradient = copies_.data() + at;
        at += std::size_t(buf.size);
      }
  }

  std::int64_t count() const { return blocks_; }
  std::int64_t begin(std::int64_t k) const { return std::min(count_, k * per_block_); }
  std::int64_t end(std::int64_t k) const { return std::min(count_, (k + 1) * per_block_); }
  // The parameter set of block k: values and tangents as given, gradients into the block's copies.
  ParamSet& set(std::int64_t k) { return sets_[std::size_t(k)]; }

  // Adds every block's copies into the given set's gradient arrays, block 0 first.
  void reduce() {
    for (std::int64_t k = 0; k < blocks_; ++k)
      for (int b = 0; b < max_param_buffers; ++b) {
        const ParamBuffer& from = sets_[std::size_t(k)].buffers[b];
        float* to = target_.buffers[b].gradient;
        if (!to || from.size <= 0) continue;
        for (std::int32_t i = 0; i < from.size; ++i) to[i] += from.gradient[i];
      }
  }

 private:
  ParamSet target_;
  std::int64_t count_ = 0, blocks_ = 1, per_block_ = 0;
  std::vector<float> copies_;
  std::vector<ParamSet> sets_;
};

}  // namespace difftrans::ad
