// The Fresnel + refraction + Beer–Lambert kernel (cuda/optics_probe.hpp) over a
// cycled set of 4096 inputs, as float, Dual<float,1>, Dual<float,8> and
// Var<float> (record + backward), so the gradient-to-primal cost ratio reads
// off one run. Target: reverse mode within 4x of the float primal.
#include "../tests/support/optics_probe.hpp"
#include "support/ratio_reporter.hpp"

namespace dc = dt_test;
namespace ad = difftrans::ad;

namespace {

const std::vector<dc::OpticsItem>& items() {
  static const std::vector<dc::OpticsItem> set = dc::make_optics_items(4096, 11);
  return set;
}

template <class S>
void run_probe(benchmark::State& state) {
  const auto& in = items();
  ad::Tape<float> tape(dc::optics_probe_tape_capacity);
  std::size_t i = 0;
  for (auto _ : state) {
    dc::OpticsResult r = dc::optics_probe_gradient<S>(in[i], &tape);
    benchmark::DoNotOptimize(r);
    i = (i + 1) & (in.size() - 1);
  }
  state.SetItemsProcessed(state.iterations());
  if constexpr (ad::is_var_v<S>) state.counters["tape_nodes"] = double(tape.size());
}

void optics_float(benchmark::State& s) { run_probe<float>(s); }
void optics_dual1(benchmark::State& s) { run_probe<ad::Dual<float, 1>>(s); }
void optics_dual8(benchmark::State& s) { run_probe<ad::Dual<float, 8>>(s); }
void optics_var(benchmark::State& s) { run_probe<ad::Var<float>>(s); }

}  // namespace

BENCHMARK(optics_float);
BENCHMARK(optics_dual1);
BENCHMARK(optics_dual8);
BENCHMARK(optics_var);

int main(int argc, char** argv) { return dt_bench::run_with_ratios(argc, argv, {{"optics_", "optics_float"}}); }
