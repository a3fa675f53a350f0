// Silhouette + analytic anti-aliasing per 256² view on spot and bunny (shared
// data; an icosphere of similar size stands in when a file is missing),
// cycling through 8 protocol cameras: rasterization alone, the float AA mask,
// the mask's gradient (reverse mode, from an L1 loss), and the smoothness term
// with its gradient. Items are views; the ratio table reads off gradient / mask.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>

#include "difftrans/render/silhouette.hpp"
#include "support/ratio_reporter.hpp"

namespace dr = difftrans::render;
namespace ds = difftrans::scene;
using difftrans::Vec3f;

namespace {

// "v x y z" and "f a b c ..." (a/b/c tokens, polygons fanned), centred on the
// origin and scaled to a longest side of 1 (PROTOCOL.md).
bool read_obj(const std::string& path, std::vector<float>& pos, std::vector<std::int32_t>& tris) {
  std::ifstream in(path);
  if (!in) return false;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "v") {
      float x = 0, y = 0, z = 0;
      ls >> x >> y >> z;
      pos.insert(pos.end(), {x, y, z});
    } else if (tag == "f") {
      std::vector<std::int32_t> f;
      std::string tok;
      while (ls >> tok) {
        const int i = std::stoi(tok.substr(0, tok.find('/')));
        f.push_back(i > 0 ? i - 1 : std::int32_t(pos.size() / 3) + i);
      }
      for (std::size_t k = 2; k < f.size(); ++k) tris.insert(tris.end(), {f[0], f[k - 1], f[k]});
    }
  }
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (std::size_t i = 0; i < pos.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], pos[i]);
    hi[i % 3] = std::max(hi[i % 3], pos[i]);
  }
  const float s = 1.0f / std::max(hi[0] - lo[0], std::max(hi[1] - lo[1], hi[2] - lo[2]));
  for (std::size_t i = 0; i < pos.size(); ++i) pos[i] = (pos[i] - 0.5f * (lo[i % 3] + hi[i % 3])) * s;
  return !tris.empty();
}

// Icosphere of radius 1/2 with 20·4^levels triangles (stand-in mesh).
void icosphere(int levels, std::vector<float>& pos, std::vector<std::int32_t>& tris) {
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  pos = {-1, t, 0, 1, t, 0, -1, -t, 0, 1, -t, 0, 0, -1, t, 0, 1, t, 0, -1, -t, 0, 1, -t, t, 0, -1, t, 0, 1, -t, 0, -1, -t, 0, 1};
  tris = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4, 11, 10, 2, 10, 7, 6, 7, 1, 8,
          3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8, 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    const auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      for (int k = 0; k < 3; ++k) pos.push_back(0.5f * (pos[3 * a + k] + pos[3 * b + k]));
      return mid[key] = int(pos.size() / 3) - 1;
    };
    std::vector<std::int32_t> next;
    for (std::size_t i = 0; i < tris.size(); i += 3) {
      const int a = tris[i], b = tris[i + 1], c = tris[i + 2];
      const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      next.insert(next.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    tris.swap(next);
  }
  for (std::size_t v = 0; v < pos.size() / 3; ++v) {
    const float l = std::sqrt(pos[3 * v] * pos[3 * v] + pos[3 * v + 1] * pos[3 * v + 1] + pos[3 * v + 2] * pos[3 * v + 2]);
    for (int k = 0; k < 3; ++k) pos[3 * v + k] *= 0.5f / l;
  }
}

struct Subject {
  ds::TriangleMesh mesh;
  dr::TriangleNeighbors neighbors;
  std::vector<ds::Camera> cameras;
  std::vector<std::vector<float>> targets;  // a target mask per view: the mesh scaled by 1.05
};

const Subject& subject(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Subject>> cache;
  auto& s = cache[name];
  if (s) return *s;
  s = std::make_unique<Subject>();
  std::vector<float> pos;
  std::vector<std::int32_t> tris;
  if (!read_obj(std::string(DIFFTRANS_SHARED_DATA_DIR) + "/meshes/" + name + ".obj", pos, tris)) {
    std::fprintf(stderr, "silhouette bench: %s.obj not found, using an icosphere\n", name.c_str());
    icosphere(name == "spot" ? 4 : 6, pos, tris);
  }
  s->mesh = ds::TriangleMesh(pos, tris);
  s->neighbors = dr::TriangleNeighbors::build(s->mesh);
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
    dr::mask_l1(m, s.targets[i].data(), adjoint.data());
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
    benchmark::DoNotOptimize(dr::smoothness_gradient(s.mesh, s.cameras[i], grad.data()));
    i = (i + 1) % s.cameras.size();
  }
  counters(state, s, 0.0);
}

void neighbors(benchmark::State& state, const std::string& name) {
  const Subject& s = subject(name);
  for (auto _ : state) benchmark::DoNotOptimize(dr::TriangleNeighbors::build(s.mesh).across.data());
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
