// Device path of the tracer: a glass sphere (grid absorption, equirect
// environment) and spot rendered on the GPU through the portable BVH —
// image (float), derivative along the IoR (Dual<float, 1>) and gradient
// (Var<float>, per-thread tape) — compared with the host passes, which use
// Embree. Exits 77 (skipped) when no CUDA device is present; the same
// kernels run on the host in tests/accel/bvh.test.cpp.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "difftrans/cuda/render.cuh"
#include "render_reference.hpp"
#include "support/shapes.hpp"

namespace dc = difftrans::cuda;
namespace dr = difftrans::render;
using difftrans::Vec3f;
using difftrans::Vec3i;

namespace {

dr::HostScene make_scene(const dt_test::Shape& shape) {
  dr::HostScene s(shape.positions, shape.triangles, "device test");
  s.ior = 1.45f;
  s.set_environment_map(dt_test::smooth_sky(32, 16), 32, 16);
  std::vector<float> raw(4 * 4 * 4 * 3);
  for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = difftrans::scene::raw_from_sigma(0.2f + 0.1f * float(i % 7));
  s.set_grid_absorption(Vec3i(4, 4, 4), Vec3f(-0.55f), Vec3f(0.55f), raw);
  return s;
}

// Share of entries where a and b differ by more than tol (relative to max(1, |b|)).
double share_differing(const std::vector<float>& a, const std::vector<float>& b, double tol, double* max_diff) {
  std::size_t bad = 0;
  *max_diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = std::abs(double(a[i]) - double(b[i]));
    *max_diff = std::max(*max_diff, d);
    bad += !(d <= tol * std::max(1.0, std::abs(double(b[i]))));
  }
  return a.empty() ? 0.0 : double(bad) / double(a.size());
}

// |a − b| / |b| over whole arrays.
double relative_l2(const std::vector<float>& a, const std::vector<float>& b) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    den += double(b[i]) * b[i];
  }
  return std::sqrt(num / std::max(den, 1e-30));
}

int compare_scene(const char* name, const dt_test::Shape& shape) {
  const dr::HostScene s = make_scene(shape);
  const difftrans::accel::Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(),
                                  s.mesh.num_triangles(), name);
  const dc::DeviceScene ds(s, bvh);
  const auto cam = difftrans::scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, 64, 64);
  dc::PassOptions opt;
  opt.trace.max_depth = 4;
  opt.samples_per_axis = 2;
  int failures = 0;
  const auto expect = [&](bool ok, const char* what, double a, double b) {
    std::printf("  %-40s %-4s (%.3g, %.3g)\n", what, ok ? "ok" : "FAIL", a, b);
    failures += !ok;
  };
  std::printf("%s:\n", name);

  // image
  dc::DevicePassStats dst;
  const std::vector<float> dev = dc::render_image(ds, cam, opt, &dst);
  const std::vector<float> host = dt_test::host_render_image(s, cam, opt.trace, opt.samples_per_axis);
  double max_diff = 0;
  const double share = share_differing(dev, host, 1e-4, &max_diff);
  expect(share <= 0.002, "image: share of values off by > 1e-4", share, max_diff);
  expect(dst.hits > dst.rays / 10, "image: rays hit the object", double(dst.hits), double(dst.rays));
  std::printf("  image: %llu rays, %llu segments in %.3f ms: %.1f M segments/s\n", (unsigned long long)dst.rays,
              (unsigned long long)dst.segments, dst.milliseconds, double(dst.segments) / dst.milliseconds * 1e-3);

  // derivative along the IoR
  const float one = 1.0f;
  const float* direction[dr::param_count] = {nullptr, &one, nullptr, nullptr};
  const dc::ImageDerivative dd = dc::render_derivative(ds, cam, direction, opt);
  dc::ImageDerivative hd;
  dt_test::host_render_derivative(s, cam, direction, opt.trace, opt.samples_per_axis, hd.value, hd.derivative);
  const double share_v = share_differing(dd.value, hd.value, 1e-4, &max_diff);
  expect(share_v <= 0.002, "Dual: value share off by > 1e-4", share_v, max_diff);
  const double rel_d = relative_l2(dd.derivative, hd.derivative);
  expect(rel_d <= 1e-3, "Dual: relative L2 of d/dIoR", rel_d, 0.0);

  // gradient of sum(adjoint · image)
  std::vector<float> adjoint(dev.size());
  for (std::size_t i = 0; i < adjoint.size(); ++i) adjoint[i] = 0.5f + 0.5f * std::sin(0.37f * float(i));
  dr::SceneGradient dg(s), hg(s);
  dc::DevicePassStats gst;
  dc::render_gradient(ds, cam, adjoint.data(), dg, opt, &gst);
  const int host_max_tape =
      dt_test::host_render_gradient(s, cam, adjoint.data(), hg, opt.trace, opt.samples_per_axis);
  std::printf("  gradient: %llu of %llu rays overflowed the device tape (max %u nodes; host max %d)\n",
              (unsigned long long)gst.overflowed_rays, (unsigned long long)gst.rays, gst.max_tape_nodes,
              host_max_tape);
  expect(gst.overflowed_rays == 0, "Var: no tape overflow", double(gst.overflowed_rays), 0.0);
  expect(std::abs(dg.ior[0] - hg.ior[0]) <= 1e-3 * std::abs(hg.ior[0]) + 1e-4, "Var: dL/dIoR", dg.ior[0], hg.ior[0]);
  const double rel_p = relative_l2(dg.positions, hg.positions);
  expect(rel_p <= 2e-3, "Var: relative L2 of dL/dpositions", rel_p, 0.0);
  const double rel_a = relative_l2(dg.absorption, hg.absorption);
  expect(rel_a <= 2e-3, "Var: relative L2 of dL/dabsorption", rel_a, 0.0);
  const double rel_e = relative_l2(dg.environment, hg.environment);
  expect(rel_e <= 2e-3, "Var: relative L2 of dL/denvironment", rel_e, 0.0);
  return failures;
}

// Tapes in each thread's local memory (GradientPixel<4096>) against tapes
// cut from a pool: a homogeneous-absorption sphere at depth 4, whose rays
// record fewer than 4096 nodes (checked on the host in tests/accel/bvh.test.cpp).
int compare_local_tapes() {
  dr::HostScene s = make_scene(dt_test::make_icosphere(0.5f, 3));
  s.set_homogeneous_absorption(Vec3f(0.3f, 0.6f, 1.2f));
  const difftrans::accel::Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(),
                                  s.mesh.num_triangles(), "sphere");
  const dc::DeviceScene ds(s, bvh);
  const auto cam = difftrans::scene::look_at_camera(Vec3f(0.3f, 0.4f, 1.6f), Vec3f(0.0f), Vec3f(0, 1, 0), 0.9f, 64, 64);
  dc::PassOptions opt;
  opt.trace.max_depth = 4;
  std::vector<float> adjoint(std::size_t(cam.width) * cam.height * 3);
  for (std::size_t i = 0; i < adjoint.size(); ++i) adjoint[i] = 0.5f + 0.5f * std::cos(0.21f * float(i));
  dr::SceneGradient local(s), pooled(s), host(s);
  dc::DevicePassStats ls, ps;
  dc::render_gradient<4096, 512>(ds, cam, adjoint.data(), local, opt, &ls);
  dc::render_gradient(ds, cam, adjoint.data(), pooled, opt, &ps);
  dt_test::host_render_gradient(s, cam, adjoint.data(), host, opt.trace, opt.samples_per_axis);
  const double rel_lp = relative_l2(local.positions, pooled.positions);
  const double rel_lh = relative_l2(local.positions, host.positions);
  const bool ok = ls.overflowed_rays == 0 && ps.overflowed_rays == 0 && rel_lp <= 1e-5 && rel_lh <= 2e-3 &&
                  std::abs(local.ior[0] - host.ior[0]) <= 1e-3 * std::abs(host.ior[0]) + 1e-4;
  std::printf("local tapes: %.3f ms (pooled %.3f ms), overflow %llu/%llu, |local-pooled| %.3g, |local-host| %.3g: %s\n",
              ls.milliseconds, ps.milliseconds, (unsigned long long)ls.overflowed_rays,
              (unsigned long long)ps.overflowed_rays, rel_lp, rel_lh, ok ? "ok" : "FAIL");
  return ok ? 0 : 1;
}

}  // namespace

int main() {
  if (dc::device_count() == 0) {
    std::printf("no CUDA device: device test skipped (the same kernels are tested on the host)\n");
    return 77;
  }
  int failures = compare_scene("sphere", dt_test::make_icosphere(0.5f, 3));
  failures += compare_scene(
      "spot", dt_test::load_normalized_mesh(std::string(DIFFTRANS_DATA_DIR) + "/meshes/spot.obj"));
  failures += compare_local_tapes();
  std::printf("%s\n", failures == 0 ? "all device results agree with the host" : "device results differ");
  return failures == 0 ? 0 : 1;
}
