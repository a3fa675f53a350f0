// Wall time of a piece of work for the report programs of bench/: the best of
// a few runs (the least disturbed by the rest of a shared machine).
#pragma once

#include <algorithm>
#include <chrono>
#include <functional>

namespace dt_bench {

inline double best_seconds(const std::function<void()>& f, int repeats = 1) {
  double best = 1e300;
  for (int r = 0; r < std::max(1, repeats); ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

}  // namespace dt_bench
