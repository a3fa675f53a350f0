// Block gradients: the blocks cover the items once, each block scatters into
// its own copy, and reduce() adds them to the real arrays in block order.
#include <doctest/doctest.h>

#include <cstdint>
#include <vector>

#include "difftrans/ad/block_gradients.hpp"

namespace ad = difftrans::ad;

TEST_CASE("block gradients: blocks partition the items, copies sum in block order") {
  std::vector<float> values(4, 1.0f), grad(4, 0.5f), unused(3, 0.0f);
  ad::ParamSet set;
  set.buffers[0].values = values.data();
  set.buffers[0].size = 4;
  set.buffers[0].gradient = grad.data();
  set.buffers[1].values = unused.data();
  set.buffers[1].size = 3;  // no gradient array: no copy, never written
  ad::BlockGradients blocks(set, 100, 8, 16);
  CHECK(blocks.count() == 7);  // ceil(100 / 16) blocks, at most 8
  std::int64_t covered = 0;
  for (std::int64_t k = 0; k < blocks.count(); ++k) {
    CHECK(blocks.begin(k) == covered);
    covered = blocks.end(k);
    CHECK(blocks.set(k).buffers[0].gradient != grad.data());
    CHECK(blocks.set(k).buffers[1].gradient == nullptr);
    for (std::int64_t i = blocks.begin(k); i < blocks.end(k); ++i) blocks.set(k).buffers[0].gradient[i % 4] += 1.0f;
  }
  CHECK(covered == 100);
  CHECK(grad[0] == 0.5f);  // nothing reaches the real array before reduce()
  blocks.reduce();
  for (float g : grad) CHECK(g == 25.5f);
  CHECK(ad::BlockGradients(set, 0).count() == 1);
}
