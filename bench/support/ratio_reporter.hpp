// A Google Benchmark console reporter that, after the usual table, prints
// each benchmark's items-per-second as a ratio to a named baseline, so that
// cost ratios (gradient / primal, tracer / Embree) are read off one run.
#pragma once

#include <benchmark/benchmark.h>

#include <cstdio>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace dt_bench {

class RatioReporter : public benchmark::ConsoleReporter {
 public:
  // Benchmarks whose name starts with `prefix` are compared with the one named `baseline`.
  void add_group(std::string prefix, std::string baseline) { groups_.emplace_back(std::move(prefix), std::move(baseline)); }

  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) {
      if (r.run_type != Run::RT_Iteration || r.error_occurred) continue;
      const auto it = r.counters.find("items_per_second");
      if (it != r.counters.end()) rates_[r.benchmark_name()] = double(it->second);
    }
  }

  void Finalize() override {
    ConsoleReporter::Finalize();
    for (const auto& [prefix, baseline] : groups_) {
      const auto base = rates_.find(baseline);
      if (base == rates_.end()) continue;
      std::printf("\ncost relative to %s (%.3g items/s): time ratio = baseline rate / rate\n", baseline.c_str(),
                  base->second);
      for (const auto& [name, rate] : rates_)
        if (name.rfind(prefix, 0) == 0) std::printf("  %-48s %10.3g items/s   x%.2f\n", name.c_str(), rate, base->second / rate);
    }
    std::fflush(stdout);
  }

 private:
  std::vector<std::pair<std::string, std::string>> groups_;
  std::map<std::string, double> rates_;
};

// main() for a benchmark program with ratio groups; JSON output flags
// (--benchmark_out=FILE --benchmark_out_format=json) work as usual.
inline int run_with_ratios(int argc, char** argv, const std::vector<std::pair<std::string, std::string>>& groups) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  for (const auto& [prefix, baseline] : groups) reporter.add_group(prefix, baseline);
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}

}  // namespace dt_bench
