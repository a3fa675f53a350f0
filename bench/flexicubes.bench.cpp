// FlexiCubes extraction time at 32³, 64³ and 128³, single-threaded, cycling
// over three noisy sphere-like SDFs with random deformations and weights:
//   float  flexicubes_extract<float>, every unknown a constant
//   var    flexicubes_extract<Var<float>> with every unknown differentiable
//          (leaves through ParamReader), loss = sum of vertex coordinates,
//          backward and scatter into the gradient arrays
// Items = grid cubes, so the printed ratios are gradient time over float time.
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "difftrans/geometry/flexicubes.hpp"
#include "support/ratio_reporter.hpp"

namespace ad = difftrans::ad;
namespace dg = difftrans::geometry;
using difftrans::Vec3f;

namespace {

constexpr int num_inputs = 3;

struct Input {
  dg::FlexiCubesGrid grid;
  std::vector<float> sdf, deform, alpha, beta, gamma;
  std::vector<float> grad[5];
  ad::ParamSet set;

  dg::FlexiCubesInputs inputs(bool differentiable) const {
    const std::vector<float>* v[5] = {&sdf, &deform, &alpha, &beta, &gamma};
    dg::FlexiCubesInputs in;
    difftrans::ad::ParamSource* s[5] = {&in.sdf, &in.deform, &in.alpha, &in.beta, &in.gamma};
    for (int b = 0; b < 5; ++b) *s[b] = {v[b]->data(), std::int32_t(v[b]->size()), differentiable ? b : -1};
    return in;
  }
};

std::unique_ptr<Input> make_input(int res, int variant) {
  auto in = std::make_unique<Input>();
  in->grid.res = res;
  std::mt19937 rng(std::uint32_t(100 * res + variant));
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const int V = res + 1;
  const Vec3f c(0.05f * float(variant), -0.03f * float(variant), 0.02f);
  const float r = 0.55f + 0.05f * float(variant);
  in->sdf.resize(std::size_t(V) * V * V);
  for (int k = 0; k < V; ++k)
    for (int j = 0; j < V; ++j)
      for (int i = 0; i < V; ++i) {
        const Vec3f p = in->grid.vertex_position(i, j, k) - c;
        const float bumps = 0.06f * std::sin(7.0f * p.x + float(variant)) * std::sin(5.0f * p.y) * std::sin(6.0f * p.z);
        in->sdf[std::size_t(in->grid.vertex_index(i, j, k))] = glm::length(p) - r + bumps;
      }
  in->deform.resize(3 * in->sdf.size());
  in->alpha.resize(8 * std::size_t(in->grid.num_cubes()));
  in->beta.resize(12 * std::size_t(in->grid.num_cubes()));
  in->gamma.resize(std::size_t(in->grid.num_cubes()));
  for (auto* v : {&in->deform, &in->alpha, &in->beta, &in->gamma})
    for (float& x : *v) x = 0.5f * u(rng);
  std::vector<float>* v[5] = {&in->sdf, &in->deform, &in->alpha, &in->beta, &in->gamma};
  for (int b = 0; b < 5; ++b) {
    in->grad[b].assign(v[b]->size(), 0.0f);
    in->set.buffers[b].values = v[b]->data();
    in->set.buffers[b].size = std::int32_t(v[b]->size());
    in->set.buffers[b].gradient = in->grad[b].data();
  }
  return in;
}

Input& input(int res, int variant) {
  static std::map<std::pair<int, int>, std::unique_ptr<Input>> cache;
  auto& slot = cache[{res, variant}];
  if (!slot) slot = make_input(res, variant);
  return *slot;
}

void flexicubes_float(benchmark::State& state) {
  const int res = int(state.range(0));
  for (int v = 0; v < num_inputs; ++v) input(res, v);
  int v = 0;
  std::size_t triangles = 0;
  for (auto _ : state) {
    const Input& in = input(res, v);
    const auto mesh = dg::flexicubes_extract<float>(in.grid, in.inputs(false));
    benchmark::DoNotOptimize(mesh.vertices.data());
    triangles = mesh.triangles.size() / 3;
    v = (v + 1) % num_inputs;
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(res) * res * res);
  state.counters["triangles"] = double(triangles);
}

void flexicubes_var(benchmark::State& state) {
  const int res = int(state.range(0));
  for (int v = 0; v < num_inputs; ++v) input(res, v);
  // tape and leaf log sized from the largest input's float mesh
  std::size_t most = 0;
  for (int v = 0; v < num_inputs; ++v) {
    const Input& in = input(res, v);
    const auto m = dg::flexicubes_extract<float>(in.grid, in.inputs(false));
    most = std::max(most, m.vertices.size() + std::size_t(m.num_dual_vertices));
  }
  const std::int32_t capacity = std::int32_t(160 * most + 1024);
  ad::Tape<float> tape(capacity);
  std::vector<ad::LeafRecord> log(std::size_t(48 * most + 1024));
  int v = 0;
  std::int32_t nodes = 0;
  for (auto _ : state) {
    Input& in = input(res, v);
    tape.reset();
    ad::ParamReader<ad::Var<float>> reader(&in.set, &tape, log.data(), std::int32_t(log.size()));
    const auto mesh = dg::flexicubes_extract<ad::Var<float>>(in.grid, in.inputs(true), reader);
    ad::Var<float> loss(0.0f);
    for (const auto& p : mesh.vertices) loss = loss + p.x + p.y + p.z;
    if (tape.overflowed() || reader.overflowed()) {
      state.SkipWithError("tape or leaf log overflowed");
      break;
    }
    tape.backward(loss);
    reader.scatter();
    nodes = tape.size();
    benchmark::DoNotOptimize(in.grad[0].data());
    v = (v + 1) % num_inputs;
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(res) * res * res);
  state.counters["tape_nodes"] = double(nodes);
}

}  // namespace

BENCHMARK(flexicubes_float)->Arg(32)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK(flexicubes_var)->Arg(32)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) {
  return dt_bench::run_with_ratios(argc, argv,
                                   {{"flexicubes_var/32", "flexicubes_float/32"},
                                    {"flexicubes_var/64", "flexicubes_float/64"},
                                    {"flexicubes_var/128", "flexicubes_float/128"}});
}
