// The device passes against the host passes, in one run: for each mesh at
// one view, the primal image (render_image: the wavefront with its registers
// capped, the default; without the cap as device_primal_uncapped; a thread
// per pixel as device_primal_per_pixel) and the gradient (render_gradient,
// dLoss/dpixel = 1: branches as work items, the default; a thread per pixel
// as device_gradient_per_pixel) on the GPU and on the host thread pool (its size from
// DIFFTRANS_THREADS), with rays and segments per second. Prints one JSON line
// per mesh; scripts/gpu_check.sh runs it with all cores and with 2 threads.
//
// usage: bench_device_speed [--size 512] [--depth 16] [--spp 4] [--repeats 3]
//                           [--host-only] [--device-only] [MESH ...]
//   MESH: names in data/meshes (default: spot bunny horse monkey)
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "difftrans/cuda/render.cuh"
#include "device/speed_host.hpp"
#include "support/timing.hpp"

namespace dc = difftrans::cuda;
namespace dr = difftrans::render;
using difftrans::Vec3f;

int main(int argc, char** argv) {
  int size = 512, depth = 16, spp = 4, repeats = 3;
  bool host = true, device = true;
  std::vector<std::string> meshes;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_device_speed: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return std::atoi(argv[++i]);
    };
    if (a == "--size") size = value();
    else if (a == "--depth") depth = value();
    else if (a == "--spp") spp = value();
    else if (a == "--repeats") repeats = std::max(1, value());
    else if (a == "--host-only") device = false;
    else if (a == "--device-only") host = false;
    else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "bench_device_speed: unknown option %s\n", a.c_str());
      return 2;
    } else meshes.push_back(a);
  }
  if (meshes.empty()) meshes = {"spot", "bunny", "horse", "monkey"};
  int n = 1;
  while ((n + 1) * (n + 1) <= spp) ++n;  // samples per axis
  if (device && dc::device_count() == 0) {
    std::fprintf(stderr, "bench_device_speed: no CUDA device\n");
    return 77;
  }
  dr::TraceSettings trace;
  trace.max_depth = depth;
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.4f, 0.5f, 1.0f), size, size);
  const double rays = double(size) * double(size) * double(n * n);
  for (const std::string& mesh : meshes) {
    const dr::HostScene s = dt_bench::speed_scene(mesh);
    std::printf("{\"mesh\": \"%s\", \"size\": %d, \"depth\": %d, \"spp\": %d", mesh.c_str(), size, depth, n * n);
    if (host) {
      const dt_bench::HostTimes t = dt_bench::time_host_passes(s, cam, trace, n, repeats);
      std::printf(", \"host_threads\": %d, \"host_primal_s\": %.6f, \"host_gradient_s\": %.6f,"
                  " \"host_primal_Mrays_s\": %.2f, \"host_primal_Msegments_s\": %.2f, \"host_gradient_Msegments_s\": %.2f",
                  t.threads, t.primal_seconds, t.gradient_seconds, rays / t.primal_seconds * 1e-6,
                  double(t.primal_segments) / t.primal_seconds * 1e-6,
                  double(t.gradient_segments) / t.gradient_seconds * 1e-6);
    }
    if (device) {
      const difftrans::accel::Bvh bvh(s.mesh.positions.data(), s.mesh.num_vertices(), s.mesh.triangles.data(),
                                      s.mesh.num_triangles(), mesh);
      const dc::DeviceScene ds(s, bvh);
      dc::PassOptions opt;
      opt.trace = trace;
      opt.samples_per_axis = n;
      dc::PassOptions per_pixel = opt, uncapped = opt, pixel_gradient = opt;
      per_pixel.wavefront = false;
      uncapped.wavefront_capped = false;
      pixel_gradient.tree_gradient = false;
      dc::DevicePassStats ps, gs, pps, ups, pgs;
      double primal_ms = 1e300, gradient_ms = 1e300, pixel_ms = 1e300, uncapped_ms = 1e300, pixel_gradient_ms = 1e300;
      const std::vector<float> adjoint(std::size_t(size) * std::size_t(size) * 3, 1.0f);
      dc::render_image(ds, cam, opt, &ps);  // warm-up
      for (int r = 0; r < repeats; ++r) {
        dc::render_image(ds, cam, opt, &ps);
        primal_ms = std::min(primal_ms, ps.milliseconds);
        dc::render_image(ds, cam, per_pixel, &pps);
        pixel_ms = std::min(pixel_ms, pps.milliseconds);
        dc::render_image(ds, cam, uncapped, &ups);
        uncapped_ms = std::min(uncapped_ms, ups.milliseconds);
        dr::SceneGradient grad(s);
        dc::render_gradient(ds, cam, adjoint.data(), grad, opt, &gs);
        gradient_ms = std::min(gradient_ms, gs.milliseconds);
        dr::SceneGradient pgrad(s);
        dc::render_gradient(ds, cam, adjoint.data(), pgrad, pixel_gradient, &pgs);
        pixel_gradient_ms = std::min(pixel_gradient_ms, pgs.milliseconds);
      }
      std::printf(", \"device_primal_ms\": %.4f, \"device_gradient_ms\": %.4f, \"device_primal_Mrays_s\": %.2f,"
                  " \"device_primal_Msegments_s\": %.2f, \"device_gradient_Msegments_s\": %.2f,"
                  " \"device_gradient_waves\": %d, \"device_gradient_redone_pixels\": %lld",
                  primal_ms, gradient_ms, rays / primal_ms * 1e-3, double(ps.segments) / primal_ms * 1e-3,
                  double(gs.segments) / gradient_ms * 1e-3, gs.waves.waves, (long long)gs.waves.redone_pixels);
      std::printf(", \"device_primal_launches\": %d, \"device_primal_per_pixel_ms\": %.4f,"
                  " \"device_primal_per_pixel_Msegments_s\": %.2f, \"device_primal_uncapped_ms\": %.4f,"
                  " \"device_primal_uncapped_Msegments_s\": %.2f",
                  ps.wavefront.launches, pixel_ms, double(pps.segments) / pixel_ms * 1e-3, uncapped_ms,
                  double(ups.segments) / uncapped_ms * 1e-3);
      std::printf(", \"device_gradient_tree_launches\": %d, \"device_gradient_tree_waves\": %d,"
                  " \"device_gradient_tree_redone\": %lld, \"device_gradient_longest_tape\": %u,"
                  " \"device_gradient_per_pixel_ms\": %.4f, \"device_gradient_per_pixel_Msegments_s\": %.2f",
                  gs.tree.launches, gs.tree.waves, (long long)gs.tree.redone, gs.max_tape_nodes, pixel_gradient_ms,
                  double(pgs.segments) / pixel_gradient_ms * 1e-3);
    }
    std::printf("}\n");
    std::fflush(stdout);
  }
  return 0;
}
