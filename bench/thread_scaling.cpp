// One thread count's time for the image passes (used by
// bench/thread_scaling.sh, which runs it at 1, 2, 4, ... threads and reports
// the parallel efficiency): the primal render (render_image) and the gradient
// (render_gradient, streamed) of spot under venice_sunset, 128 x 128, depth
// 16, roulette below 0.01, 2 x 2 samples per pixel; the best of --repeats.
// The pool's size comes from DIFFTRANS_THREADS. Prints one JSON line.
//
// usage: thread_scaling [--size 128] [--repeats 3]
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "difftrans/render/passes.hpp"
#include "support/scenes.hpp"
#include "support/timing.hpp"

namespace dr = difftrans::render;
using difftrans::Vec3f;

int main(int argc, char** argv) {
  int size = 128, repeats = 3;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--size") size = std::atoi(argv[i + 1]);
    else if (a == "--repeats") repeats = std::max(1, std::atoi(argv[i + 1]));
    else {
      std::fprintf(stderr, "thread_scaling: unknown option %s\nusage: thread_scaling [--size 128] [--repeats 3]\n",
                   a.c_str());
      return 2;
    }
  }
  const dr::HostScene s = dt_bench::venice_scene("spot", 1.472f);
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.4f, 0.5f, 1.0f), size, size);
  dr::PassOptions opt;
  opt.trace.max_depth = 16;
  opt.trace.roulette = true;
  opt.trace.prune_throughput = 0.01f;
  opt.samples_per_axis = 2;
  const std::vector<float> adjoint(std::size_t(size) * std::size_t(size) * 3, 1.0f);
  dr::SceneGradient grad(s);
  const double primal = dt_bench::best_seconds([&] { dr::render_image<float>(s, cam, opt); }, repeats);
  const double gradient =
      dt_bench::best_seconds([&] { dr::render_gradient<float>(s, cam, adjoint.data(), grad, opt); }, repeats);
  std::printf("{\"threads\": %d, \"primal_seconds\": %.6f, \"gradient_seconds\": %.6f}\n",
              difftrans::ThreadPool::global().size(), primal, gradient);
  return 0;
}
