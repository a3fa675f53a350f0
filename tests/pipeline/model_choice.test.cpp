// The paired comparison of two candidate models' held-out errors
// (pipeline/model_choice.hpp).
#include "pipeline/model_choice.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace pipeline = difftrans::pipeline;

TEST_CASE("paired comparison: the mean difference, its standard error, pixels left out in either") {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // differences 1, 3, (left out), 2, (left out): mean 2, sd 1, se 1/sqrt(3)
  const std::vector<double> simpler{11.0, 13.0, nan, 12.0, 5.0};
  const std::vector<double> richer{10.0, 10.0, 4.0, 10.0, nan};
  const pipeline::PairedComparison c = pipeline::compare_paired(simpler, richer);
  CHECK(c.pixels == 3);
  CHECK(c.simpler == doctest::Approx(12.0));
  CHECK(c.richer == doctest::Approx(10.0));
  CHECK(c.gain == doctest::Approx(2.0));
  CHECK(c.standard_error == doctest::Approx(1.0 / std::sqrt(3.0)));
  CHECK(c.richer_wins(2.0, 0.1));        // 2 > 2 · 0.577 and 2 > 0.1 · 12
  CHECK_FALSE(c.richer_wins(4.0, 0.1));  // not 4 standard errors
  CHECK_FALSE(c.richer_wins(2.0, 0.2));  // not 20 % of the loss
  CHECK(c.short_of_min_gain(2.0, 0.2));        // ... but beyond 2 standard errors
  CHECK_FALSE(c.short_of_min_gain(4.0, 0.2));  // not significant either
  CHECK_FALSE(c.short_of_min_gain(2.0, 0.1));  // kept outright
  CHECK(c.relative_gain() == doctest::Approx(2.0 / 12.0));  // of the simpler one's loss on the same pixels
  CHECK(c.relative_standard_error() == doctest::Approx(1.0 / std::sqrt(3.0) / 12.0));
  CHECK(pipeline::compare_paired({nan}, {1.0}).relative_gain() == 0.0);  // no pixels: no loss to divide by
  // the richer one worse: never kept
  const pipeline::PairedComparison w = pipeline::compare_paired(richer, simpler);
  CHECK(w.gain == doctest::Approx(-2.0));
  CHECK_FALSE(w.richer_wins(0.0, 0.0));
  CHECK_FALSE(w.short_of_min_gain(0.0, 0.5));
  // one pixel: no standard error, no decision for the richer
  CHECK_FALSE(pipeline::compare_paired({2.0}, {1.0}).richer_wins(0.0, 0.0));
}

TEST_CASE("two candidates sharing a fitted parameter: each judged at the better of the two values") {
  // The demo's clear spot, in numbers: 400 held-out pixels. The homogeneous
  // candidate's fit ended nearer the true IoR than the clear one's, so at
  // their own IoRs the clear candidate's loss is 5 % higher on every pixel;
  // at the homogeneous fit's IoR the clear candidate does as well as it.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> clear_own, clear_other, tinted_own, tinted_other;
  for (int i = 0; i < 400; ++i) {
    const double base = 1.0 + 0.5 * std::sin(0.37 * i) + 0.01 * std::cos(1.3 * i);
    clear_own.push_back(1.05 * base);
    clear_other.push_back(base + 0.001 * std::sin(2.1 * i));
    tinted_own.push_back(base);
    tinted_other.push_back(1.06 * base);
  }
  const double sigmas = 2.0, min_gain = 0.01;
  // at their own IoRs alone, the tint would be kept
  REQUIRE(pipeline::compare_paired(clear_own, tinted_own).richer_wins(sigmas, min_gain));
  // each judged at the better IoR: the clear one at the other's, the tinted one at its own
  CHECK(pipeline::judged_at_other(clear_own, clear_other));
  CHECK_FALSE(pipeline::judged_at_other(tinted_own, tinted_other));
  const auto& clear = pipeline::judged_at_other(clear_own, clear_other) ? clear_other : clear_own;
  const auto& tinted = pipeline::judged_at_other(tinted_own, tinted_other) ? tinted_other : tinted_own;
  CHECK_FALSE(pipeline::compare_paired(clear, tinted).richer_wins(sigmas, min_gain));
  // pixels left out do not count; a candidate with no finite loss at the other value stays at its own
  CHECK(pipeline::mean_finite({1.0, nan, 3.0}) == doctest::Approx(2.0));
  CHECK(std::isnan(pipeline::mean_finite({nan, nan})));
  CHECK_FALSE(pipeline::judged_at_other({1.0, 2.0}, {nan, nan}));
  CHECK(pipeline::judged_at_other({nan, 2.0}, {1.0, nan}));
  CHECK(pipeline::judged_at_other({nan, nan}, {3.0, nan}));  // nothing to judge at its own value
  CHECK_FALSE(pipeline::judged_at_other({nan}, {nan}));
}
