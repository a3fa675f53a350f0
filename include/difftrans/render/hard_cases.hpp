// Rays that meet a mesh where floating point is most fragile — through an
// edge and a vertex, grazing a face, caught by total internal reflection,
// starting inside the object, through an absorption so strong that exp()
// underflows, towards the environment's seam and poles, across a zero-area
// triangle, through glass of IoR 1, along a direction that is not a number —
// and a check that the tracer's values
// and its reverse-mode gradient stay finite on each. The tests assert that
// every case is clean; `difftrans report` prints the same counts, so what
// the page says is what the tests check.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "difftrans/ad/params.hpp"
#include "difftrans/ad/tape.hpp"
#include "difftrans/geometry/procedural.hpp"
#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/tracer.hpp"
#include "difftrans/scene/envmap.hpp"

namespace difftrans::render {

struct HardCaseRay {
  Vec3f origin, direction;
};

// One hard case: a closed mesh, its material, and the rays that make it hard.
struct HardCase {
  std::string name;
  std::vector<float> positions;
  std::vector<std::int32_t> triangles;
  float ior = 1.5f;
  float sigma = 0.0f;  // homogeneous absorption per unit length (exactly 0: clear)
  std::vector<HardCaseRay> rays;
};

inline std::vector<HardCase> hard_cases() {
  const geometry::ProceduralMesh cube = geometry::box(0.5f, 0.5f, 0.5f);
  const auto on_cube = [&](std::string name, std::vector<HardCaseRay> rays) {
    HardCase c;
    c.name = std::move(name);
    c.positions = cube.positions;
    c.triangles = cube.triangles;
    c.rays = std::move(rays);
    return c;
  };
  const auto unit = [](float x, float y, float z) { return glm::normalize(Vec3f(x, y, z)); };
  std::vector<HardCase> cases;
  // x = z = 0.5 is where two faces meet; (0.5, 0.5, 0.5) a corner; along a face's diagonal
  cases.push_back(on_cube("edge and vertex hits", {{Vec3f(2.5f, 0.1f, 2.5f), unit(-1, 0, -1)},
                                                   {Vec3f(2, 2, 2), unit(-1, -1, -1)},
                                                   {Vec3f(0.2f, 0.2f, 3), Vec3f(0, 0, -1)}}));
  // tangent to the top face, and just inside it
  cases.push_back(on_cube("grazing", {{Vec3f(-3, 0.5f, 0.1f), Vec3f(1, 0, 0)}, {Vec3f(-3, 0.4999f, 0.1f), unit(1, -1e-4f, 0)}}));
  // steep internal angles: total internal reflection inside the cube
  cases.push_back(on_cube("total internal reflection", {{Vec3f(-2.0f, 0.1f, 0.3f), unit(1.0f, 0.05f, -0.45f)}}));
  cases.push_back(on_cube("camera inside the object", {{Vec3f(0.1f, -0.1f, 0.05f), unit(0.3f, 0.2f, -1.0f)}}));
  HardCase dark = on_cube("exp underflow (absorption 1e6)", {{Vec3f(0.2f, 0.1f, 3), Vec3f(0, 0, -1)}});
  dark.sigma = 1e6f;
  cases.push_back(std::move(dark));
  // the map's seam is towards +Z, its poles are ±Y; seen straight through the cube
  cases.push_back(on_cube("environment seam and poles",
                          {{Vec3f(0, 0, -3), Vec3f(0, 0, 1)}, {Vec3f(0, -3, 0), Vec3f(0, 1, 0)}, {Vec3f(0, 3, 0), Vec3f(0, -1, 0)}}));
  HardCase index_one = on_cube("IoR = 1", {{Vec3f(0.2f, 0.1f, 3), Vec3f(0, 0, -1)}, {Vec3f(-2.0f, 0.1f, 0.3f), unit(1.0f, 0.05f, -0.45f)}});
  index_one.ior = 1.0f;
  cases.push_back(std::move(index_one));
  // a ray whose direction is not a number (a camera pose gone wrong): it must
  // miss, not abort the intersector
  cases.push_back(on_cube("direction not finite", {{Vec3f(0.2f, 0.1f, 3), Vec3f(std::nanf(""), 0, -1)},
                                                   {Vec3f(0.2f, 0.1f, 3), Vec3f(0, std::numeric_limits<float>::infinity(), -1)}}));
  // a zero-area triangle in a closed mesh: the top face (y = +0.5) as a fan
  // around its centre, plus a sliver on one of its edges
  HardCase sliver = on_cube("zero-area triangle", {{Vec3f(0.0f, 3.0f, 0.0f), Vec3f(0, -1, 0)},
                                                   {Vec3f(-0.5f, 3.0f, 0.2f), Vec3f(0, -1, 0)},
                                                   {Vec3f(0.1f, 3.0f, -0.5f), Vec3f(0, -1, 0)}});
  sliver.positions.insert(sliver.positions.end(), {0.0f, 0.5f, 0.0f});
  std::vector<std::int32_t> kept;
  for (std::size_t f = 0; f + 2 < sliver.triangles.size(); f += 3) {
    const std::int32_t a = sliver.triangles[f], b = sliver.triangles[f + 1];
    if (a == 2 && (b == 6 || b == 7)) continue;  // the top face's two triangles
    kept.insert(kept.end(), {a, b, sliver.triangles[f + 2]});
  }
  const std::int32_t c = 8;
  for (std::int32_t t : {2, 6, c, 6, 7, c, 7, 3, c, 3, 2, c, 2, 2, 6}) kept.push_back(t);
  sliver.triangles = std::move(kept);
  cases.push_back(std::move(sliver));
  return cases;
}

// What tracing one case gave: radiance components (in float, then in double
// on the gradient's pass) and gradient
// entries (reverse mode in double, every parameter of the scene) that are
// not finite, radiance below zero, rays whose tape ran out.
struct HardCaseResult {
  std::string name;
  int rays = 0;
  std::int64_t values = 0, nonfinite_values = 0, negative_values = 0;
  std::int64_t gradients = 0, nonfinite_gradients = 0;
  int tape_overflows = 0;
  bool clean() const { return nonfinite_values == 0 && negative_values == 0 && nonfinite_gradients == 0 && tape_overflows == 0; }
};

inline HardCaseResult check_hard_case(const HardCase& hc, const TraceSettings& settings) {
  HardCaseResult r;
  r.name = hc.name;
  r.rays = int(hc.rays.size());
  HostScene s(hc.positions, hc.triangles, hc.name);
  s.ior = hc.ior;
  s.set_environment_map(scene::varied_sky(24, 12), 24, 12);
  if (hc.sigma != 0.0f) s.set_homogeneous_absorption(Vec3f(hc.sigma));
  {
    const ad::ParamSet params = s.params();
    ad::ParamReader<float> reader(&params);
    for (const auto& ray : hc.rays) {
      const Vec3f L = trace<float>(s.view(false), s.accel(), reader, ray.origin, ray.direction, settings);
      for (int k = 0; k < 3; ++k) {
        ++r.values;
        r.nonfinite_values += !std::isfinite(L[k]);
        r.negative_values += L[k] < 0.0f;
      }
    }
  }
  using V = ad::Var<double>;
  SceneGradient g(s);
  ad::ParamSet params = s.params();
  g.attach(params);
  ad::Tape<double> tape(1 << 20);
  std::vector<ad::LeafRecord> log(1 << 16);
  ad::ParamReader<V> reader(&params, &tape, log.data(), std::int32_t(log.size()));
  for (const auto& ray : hc.rays) {
    tape.reset();
    reader.clear();
    const Vec3<V> L = trace<V>(s.view(true, true), s.accel(), reader, ray.origin, ray.direction, settings);
    if (tape.overflowed() || reader.overflowed()) {
      ++r.tape_overflows;
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      ++r.values;
      r.nonfinite_values += !std::isfinite(L[k].value);
      r.negative_values += L[k].value < 0.0;
    }
    tape.zero_adjoints();
    for (int k = 0; k < 3; ++k) tape.seed(L[k], 1.0);
    tape.propagate();
    reader.scatter();
  }
  g.fold_normals(s);
  for (const auto* v : {&g.positions, &g.ior, &g.absorption, &g.environment})
    for (float x : *v) {
      ++r.gradients;
      r.nonfinite_gradients += !std::isfinite(x);
    }
  return r;
}

}  // namespace difftrans::render
