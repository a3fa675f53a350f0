// Where a reverse pass sums its gradient in double. Every ray adds its
// adjoints into the gradient buffers; the IoR (one value) and the absorption
// (a few) receive millions of adds, and a float sum rounds away the low bits
// of each term the same way whatever the order: on a grid-absorbing sphere at
// 512², depth 4, dL/dIoR summed per branch in float lands 7e-4 off forward
// mode, two orders of the same adds 4e-6 apart (docs/cuda.md, "Summing the
// gradient"). DoubleSums gives those buffers double sums
// (ad::ParamBuffer::wide_gradient) for the length of a pass.
#pragma once

#include <cstddef>
#include <vector>

#include "difftrans/ad/params.hpp"
#include "difftrans/render/host_scene.hpp"

namespace difftrans::render {

// Whether a pass sums buffer b's gradient in double: the IoR and the absorption.
inline bool sums_in_double(int buffer) { return buffer == param_ior || buffer == param_absorption; }

// Double sums for the buffers of `set` that sums_in_double names and that
// have a float gradient; add_to() adds them into that gradient after the pass.
class DoubleSums {
 public:
  explicit DoubleSums(ad::ParamSet& set) : set_(&set) {
    for (int b = 0; b < param_count; ++b)
      if (sums_in_double(b) && set.buffers[b].gradient && set.buffers[b].size > 0) {
        sums_[b].assign(std::size_t(set.buffers[b].size), 0.0);
        set.buffers[b].wide_gradient = sums_[b].data();
      }
  }
  DoubleSums(const DoubleSums&) = delete;
  DoubleSums& operator=(const DoubleSums&) = delete;

  void add_to() const {
    for (int b = 0; b < param_count; ++b)
      for (std::size_t i = 0; i < sums_[b].size(); ++i) set_->buffers[b].gradient[i] += float(sums_[b][i]);
  }

 private:
  ad::ParamSet* set_;
  std::vector<double> sums_[param_count];
};

}  // namespace difftrans::render
