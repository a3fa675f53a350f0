// Silhouette + analytic anti-aliasing per 256² view on spot and bunny (shared
// data; an icosphere of similar size stands in when a file is missing),
// cycling through 8 protocol cameras: rasterization alone, the float AA mask,
// the mask's gradient (reverse mode, from an L1 loss), and the smoothness term
// with its gradient. Items are views; the ratio table reads off gradient / mask.
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include "../tests/support/shapes.hpp"
#include "difftrans/losses/mask.hpp"
#include "difftrans/losses/screen_smoothness.hpp"
#include "difftrans/render/silhouette.hpp"
#include "support/ratio_reporter.hpp"

namespace dr = difftrans::render;
namespace ds = difftrans::scene;
namespace geometry = difftrans::geometry;
namespace losses = difftrans::losses;
using difftrans::Vec3f;

namespace {

struct Subject {
  ds::TriangleMesh mesh;
  geometry::TriangleNeighbors neighbors;
  std::vector<ds::Camera> cameras;
  std::vector<std::vector<float>> targets;  // a target mask per view: the mesh scaled by 1.05
};

const Subject& subject(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Subject>> cache;
  auto& s = cache[name];
  if (s) return *s;
  s = std::make_unique<Subject>();
  dt_test::Shape shape;
  try {
    shape = dt_test::load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/" + name + ".obj");
  } catch (const std::exception&) {
    std::fprintf(stderr, "silhouette bench: %s.obj not found, using an icosphere\n", name.c_str());
    shape = dt_test::make_icosphere(0.5f, name == "spot" ? 4 : 6);
  }
  const std::vector<float>& pos = shape.positions;
  const std::vector<std::int32_t>& tris = shape.triangles;
  s->mesh = ds::TriangleMesh(pos, tris);
  s->neighbors = geometry::TriangleNeighbors::build(s->mesh);
  std::vector<float> bigger = pos;
  for (float& x : bigger) x *= 1.05f;
  const ds::TriangleMesh target(bigger, tris);
  const Vec3f dirs[8] = {{0, 0, 1}, {1, 0.3f, 0}, {0, 0.2f, -1}, {-1, -0.2f, 0.1f},
                         {0.6f, 0.8f, 0.4f}, {-0.5f, 0.4f, -0.7f}, {0.7f, -0.5f, 0.5f}, {0.1f, 1, 0.05f}};
  for (const Vec3f& d : dirs) {
    s->cameras.push_back(ds::protocol_camera(d, 256, 256));
    s->targets.push_back(dr::silhouette_mask(target, s->cameras.back(), &s->neighbors));
  }
  return *s;
}

void counters(benchmark::State& state, const Subject& s, double crossings) {
  state.SetItemsProcessed(state.iterations());
  state.counters["triangles"] = double(s.mesh.num_triangles());
  if (crossings > 0) state.counters["crossings_per_view"] = crossings / double(state.iterations());
}

void raster(benchmark::State& state, const std::string& name) {
  const Subject& s = subject(name);
  std::size_t i = 0;
  for (auto _ : state) {
    const dr::Raster r = dr::rasterize(s.mesh, s.cameras[i]);
    benchmark::DoNotOptimize(r.triangle.data());
    i = (i + 1) % s.cameras.size();
  }
  counters(state, s, 0.0);
}

void mask(benchmark::State& state, const std::string& name) {
  const Subject& s = subject(name);
  std::size_t i = 0;
  double crossings = 0.0;
  for (auto _ : state) {
    const dr::SilhouetteFrame f = dr::prepare_silhouette(s.mesh, s.neighbors, s.cameras[i]);
    const std::vector<float> m = dr::antialiased_mask(f, s.mesh, s.cameras[i]);
    benchmark::DoNotOptimize(m.data());
    crossings += double(f.crossings.size());
    i = (i + 1) % s.cameras.size();
  }
  counters(state, s, crossings);
}

// Mask, L1 against the target and its gradient w.r.t. the vertices.
void gradient(benchmark::State& state, const std::string& name) {
  const Subject& s = subject(name);
  std::vector<float> grad(s.mesh.positions.size()), adjoint(256 * 256);
  std::size_t i = 0;
  double crossings = 0.0;
  for (auto _ : state) {
    std::fill(grad.begin(), grad.end(), 0.0f);
    const dr::SilhouetteFrame f = dr::prepare_silhouette(s.mesh, s.neighbors, s.cameras[i]);
    const std::vector<float> m = dr::antialiased_mask(f, s.mesh, s.cameras[i]);
    losses::mask_l1(m, s.targets[i].data(), adjoint.data());
    dr::silhouette_backward(f, s.mesh, s.cameras[i], adjoint.data(), grad.data());
    benchmark::DoNotOptimize(grad.data());
    crossings += double(f.crossings.size());
    i = (i + 1) % s.cameras.size();
  }
  counters(state, s, crossings);
}

void smoothness(benchmark::State& state, const std::string& name) {
  const Subject& s = subject(name);
  std::vector<float> grad(s.mesh.positions.size());
  std::size_t i = 0;
  for (auto _ : state) {
    std::fill(grad.begin(), grad.end(), 0.0f);
    benchmark::DoNotOptimize(losses::smoothness_gradient(s.mesh, s.cameras[i], grad.data()));
    i = (i + 1) % s.cameras.size();
  }
  counters(state, s, 0.0);
}

void neighbors(benchmark::State& state, const std::string& name) {
  const Subject& s = subject(name);
  for (auto _ : state) benchmark::DoNotOptimize(geometry::TriangleNeighbors::build(s.mesh).across.data());
  counters(state, s, 0.0);
}

}  // namespace

BENCHMARK_CAPTURE(raster, spot, std::string("spot"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(mask, spot, std::string("spot"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gradient, spot, std::string("spot"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(smoothness, spot, std::string("spot"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(neighbors, spot, std::string("spot"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(raster, bunny, std::string("bunny"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(mask, bunny, std::string("bunny"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(gradient, bunny, std::string("bunny"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(smoothness, bunny, std::string("bunny"))->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(neighbors, bunny, std::string("bunny"))->Unit(benchmark::kMillisecond)->UseRealTime();

int main(int argc, char** argv) {
  return dt_bench::run_with_ratios(argc, argv, {{"raster/spot", "mask/spot"}, {"gradient/spot", "mask/spot"},
                                                {"smoothness/spot", "mask/spot"}, {"raster/bunny", "mask/bunny"},
                                                {"gradient/bunny", "mask/bunny"}, {"smoothness/bunny", "mask/bunny"}});
}
