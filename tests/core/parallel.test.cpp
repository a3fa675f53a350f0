// The host thread pool: every index exactly once, worker ids in range,
// exceptions carried back to the caller, and the pool reusable afterwards.
#include <stdexcept>

#include "support/ad_check.hpp"

#include "difftrans/core/parallel.hpp"

TEST_CASE("parallel_for visits every index once") {
  difftrans::ThreadPool pool(4);
  CHECK(pool.size() == 4);
  for (std::int64_t count : {0, 1, 7, 1000, 100003}) {
    std::vector<std::atomic<int>> hits(static_cast<std::size_t>(count));
    std::atomic<int> bad_worker{0};
    pool.parallel_for(count, 64, [&](std::int64_t b, std::int64_t e, int w) {
      if (w < 0 || w >= 4) ++bad_worker;
      for (std::int64_t i = b; i < e; ++i) ++hits[std::size_t(i)];
    });
    int wrong = 0;
    for (auto& h : hits) wrong += h.load() != 1;
    CHECK(wrong == 0);
    CHECK(bad_worker == 0);
  }
}

TEST_CASE("exceptions reach the caller and the pool keeps working") {
  difftrans::ThreadPool pool(3);
  CHECK_THROWS_WITH(pool.parallel_for(10000, 10,
                                      [](std::int64_t b, std::int64_t, int) {
                                        if (b == 5000) throw std::runtime_error("chunk 5000 failed");
                                      }),
                    "chunk 5000 failed");
  std::atomic<std::int64_t> sum{0};
  pool.parallel_for(1000, 7, [&](std::int64_t b, std::int64_t e, int) {
    for (std::int64_t i = b; i < e; ++i) sum += i;
  });
  CHECK(sum == 999 * 1000 / 2);
}
