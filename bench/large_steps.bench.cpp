// The large-steps parameterization (optim/large_steps.hpp): factorization of
// M = I + λL and one solve of M x = u (3 columns) for an icosphere of 10,242
// vertices and a torus of 50,000, and the spot mesh remeshed by
// geometry/remesh.hpp.
// Target (issue 5): one solve for 10k and 50k vertices.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "difftrans/geometry/remesh.hpp"
#include "difftrans/optim/large_steps.hpp"
#include "../tests/support/shapes.hpp"

namespace {

namespace dg = difftrans::geometry;
namespace opt = difftrans::optim;

// Arg 0: the icosphere of level 5 (10,242 vertices); arg 1: a 250 × 200
// torus (50,000 vertices). Four jittered right-hand sides per mesh, cycled,
// so the solves are not cache-warm.
struct Case {
  dt_test::Shape shape;
  std::vector<std::vector<float>> rhs;
};

dt_test::Shape torus(int n, int m) {
  dt_test::Shape s;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double u = 2 * M_PI * i / n, v = 2 * M_PI * j / m;
      s.positions.push_back(float((1 + 0.3 * std::cos(v)) * std::cos(u)));
      s.positions.push_back(float((1 + 0.3 * std::cos(v)) * std::sin(u)));
      s.positions.push_back(float(0.3 * std::sin(v)));
    }
  const auto id = [&](int i, int j) { return (i % n) * m + j % m; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j)
      for (int k : {id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j), id(i + 1, j + 1), id(i, j + 1)})
        s.triangles.push_back(k);
  return s;
}

const Case& mesh(int which) {
  static Case cases[2];
  Case& c = cases[which];
  if (c.shape.positions.empty()) {
    c.shape = which == 0 ? dt_test::make_icosphere(1.0f, 5) : torus(250, 200);
    std::mt19937 rng{unsigned(which)};
    std::normal_distribution<float> n(0.0f, 0.01f);
    for (int k = 0; k < 4; ++k) {
      std::vector<float> r = c.shape.positions;
      for (float& v : r) v += n(rng);
      c.rhs.push_back(r);
    }
  }
  return c;
}

void factorize(benchmark::State& state) {
  const Case& c = mesh(int(state.range(0)));
  const std::int32_t nv = std::int32_t(c.shape.positions.size() / 3);
  for (auto _ : state) {
    opt::LargeSteps ls(19.0);
    ls.set_topology(c.shape.triangles, nv);
    benchmark::DoNotOptimize(ls.factorizations());
  }
  state.counters["vertices"] = nv;
}

void solve(benchmark::State& state) {
  const Case& c = mesh(int(state.range(0)));
  const std::int32_t nv = std::int32_t(c.shape.positions.size() / 3);
  opt::LargeSteps ls(19.0);
  ls.set_topology(c.shape.triangles, nv);
  std::vector<float> x(c.shape.positions.size());
  std::size_t i = 0;
  for (auto _ : state) {
    ls.from_u(c.rhs[i].data(), x.data());
    benchmark::DoNotOptimize(x.data());
    i = (i + 1) % c.rhs.size();
  }
  state.counters["vertices"] = nv;
  state.SetItemsProcessed(state.iterations() * nv);
}

// One optimizer step: backward solve, AdamUniform on u, forward solve.
void optimizer_step(benchmark::State& state) {
  const Case& c = mesh(int(state.range(0)));
  opt::LargeStepsOptimizer o(19.0);
  std::vector<float> x = c.shape.positions;
  o.reset(x, c.shape.triangles);
  std::size_t i = 0;
  for (auto _ : state) {
    o.step(x, c.rhs[i], 1e-4f);
    benchmark::DoNotOptimize(x.data());
    i = (i + 1) % c.rhs.size();
  }
  state.counters["vertices"] = double(x.size() / 3);
}

const dt_test::Shape& spot() {
  static const dt_test::Shape s = dt_test::load_normalized_mesh(DIFFTRANS_DATA_DIR "/meshes/spot.obj");
  return s;
}

// Remeshing spot (2,930 vertices, longest side 1) to L = 0.02 (about 5.4k
// vertices), 10 iterations; counters: output size and edges within [4/5 L, 4/3 L].
void remesh_spot(benchmark::State& state) {
  const dt_test::Shape& s = spot();
  dg::RemeshOptions o;
  o.target_length = float(state.range(0)) / 1000.0f;
  o.iterations = 10;
  dg::RemeshResult r;
  for (auto _ : state) {
    r = dg::remesh(s.positions, s.triangles, o);
    benchmark::DoNotOptimize(r.positions.data());
  }
  state.counters["out_vertices"] = double(r.positions.size() / 3);
  state.counters["out_triangles"] = double(r.triangles.size() / 3);
}

}  // namespace

BENCHMARK(factorize)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(solve)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(optimizer_step)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(remesh_spot)->Arg(20)->Arg(40)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
