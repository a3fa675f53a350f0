// Embree against the portable BVH (accel/bvh.hpp) on the same incoherent
// closest-hit queries, one thread: rays per second per core, for spot and
// bunny. Rays: half from a sphere around the object towards random points in
// its box, half from random points inside in random directions (like the
// tracer's secondary rays); three sets of 2^16 cycled, so no run re-traces a
// cache-warm batch. Also the BVH's build and refit times.
#include <benchmark/benchmark.h>

#include <limits>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "../tests/support/rays.hpp"
#include "../tests/support/shapes.hpp"
#include "difftrans/accel/bvh.hpp"
#include "difftrans/accel/embree.hpp"
#include "support/ratio_reporter.hpp"

namespace {

using difftrans::Vec3f;
namespace da = difftrans::accel;

using Ray = dt_test::IncoherentRay;

struct Workload {
  dt_test::Shape shape;
  std::unique_ptr<da::EmbreeScene> embree;
  std::unique_ptr<da::Bvh> bvh;
  std::vector<std::vector<Ray>> sets;
};

Workload& workload(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Workload>> cache;
  auto& w = cache[name];
  if (!w) {
    w = std::make_unique<Workload>();
    w->shape = dt_test::load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/" + name + ".obj");
    const auto nv = std::int32_t(w->shape.positions.size() / 3), nt = std::int32_t(w->shape.triangles.size() / 3);
    w->embree = std::make_unique<da::EmbreeScene>(w->shape.positions.data(), nv, w->shape.triangles.data(), nt, name);
    w->bvh = std::make_unique<da::Bvh>(w->shape.positions.data(), nv, w->shape.triangles.data(), nt, name);
    for (std::uint32_t s = 1; s <= 3; ++s) w->sets.push_back(dt_test::incoherent_rays(1 << 16, s, false));
  }
  return *w;
}

template <class Accel>
void trace_rays(benchmark::State& state, const Accel& accel, const Workload& w) {
  std::size_t set = 0;
  std::int64_t hits = 0, rays = 0;
  for (auto _ : state) {
    for (const Ray& r : w.sets[set]) {
      const auto h = accel.intersect(r.o, r.d, 0.0f, std::numeric_limits<float>::infinity());
      hits += h.prim >= 0;
      benchmark::DoNotOptimize(h);
    }
    rays += std::int64_t(w.sets[set].size());
    set = (set + 1) % w.sets.size();
  }
  state.SetItemsProcessed(rays);
  state.counters["rays_per_s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsRate);
  state.counters["hit_share"] = rays ? double(hits) / double(rays) : 0.0;
}

void embree(benchmark::State& state, std::string name) {
  const Workload& w = workload(name);
  trace_rays(state, *w.embree, w);
}

void bvh(benchmark::State& state, std::string name) {
  const Workload& w = workload(name);
  trace_rays(state, *w.bvh, w);
  state.counters["nodes"] = double(w.bvh->nodes().size());
  state.counters["depth"] = double(w.bvh->depth());
  state.counters["sah_cost"] = w.bvh->sah_cost();
}

void bvh_build(benchmark::State& state, std::string name) {
  const Workload& w = workload(name);
  const auto nv = std::int32_t(w.shape.positions.size() / 3), nt = std::int32_t(w.shape.triangles.size() / 3);
  for (auto _ : state) {
    da::Bvh b(w.shape.positions.data(), nv, w.shape.triangles.data(), nt, name);
    benchmark::DoNotOptimize(b.nodes().data());
  }
  state.SetItemsProcessed(state.iterations() * nt);  // triangles per second
}

void bvh_refit(benchmark::State& state, std::string name) {
  Workload& w = workload(name);
  for (auto _ : state) w.bvh->refit(w.shape.positions.data());
  state.SetItemsProcessed(state.iterations() * std::int64_t(w.shape.triangles.size() / 3));
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::pair<std::string, std::string>> groups;
  for (const std::string name : {"spot", "bunny"}) {
    const std::string prefix = name + "/";
    benchmark::RegisterBenchmark((prefix + "embree").c_str(), embree, name)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark((prefix + "bvh").c_str(), bvh, name)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark((prefix + "build/bvh").c_str(), bvh_build, name)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark((prefix + "refit/bvh").c_str(), bvh_refit, name)->Unit(benchmark::kMillisecond);
    groups.emplace_back(prefix + "bvh", prefix + "embree");
  }
  return dt_bench::run_with_ratios(argc, argv, groups);
}
