// How far the host passes move when only the rounding changes
// (render/rounding_sensitivity.hpp: the eye moved by one float step), over
// the tracing depth and the depth derivatives are carried to: which
// gradients are defined to float precision at all. Spot under venice_sunset,
// IoR 1.472, homogeneous absorption, protocol view, 2 × 2 samples per pixel,
// dLoss/dpixel a fixed wavy pattern. Prints one JSON line per setting.
//
// usage: conditioning [--size 256]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "difftrans/render/rounding_sensitivity.hpp"
#include "support/scenes.hpp"
#include "support/timing.hpp"

namespace dr = difftrans::render;
using difftrans::Vec3f;

int main(int argc, char** argv) {
  int size = 256;
  for (int i = 1; i < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--size" && i + 1 < argc) {
      size = std::atoi(argv[i + 1]);
    } else {
      std::fprintf(stderr, "conditioning: unknown option %s\nusage: conditioning [--size 256]\n", a.c_str());
      return 2;
    }
  }
  dr::HostScene s = dt_bench::venice_scene("spot", 1.472f);
  s.set_homogeneous_absorption(Vec3f(0.3f, 0.6f, 1.2f));
  const auto cam = difftrans::scene::protocol_camera(Vec3f(0.4f, 0.5f, 1.0f), size, size);
  std::vector<float> adjoint(std::size_t(size) * std::size_t(size) * 3);
  for (std::size_t i = 0; i < adjoint.size(); ++i) adjoint[i] = 0.5f + 0.5f * std::sin(0.37f * float(i));
  struct Setting {
    int depth, tree_depth, gradient_depth;
  };
  const Setting settings[] = {{4, 16, 0}, {8, 16, 0}, {12, 16, 0}, {16, 16, 0}, {16, 16, 8},
                              {16, 16, 4}, {16, 8, 0}, {16, 8, 4}};
  for (const Setting& st : settings) {
    dr::PassOptions opt;
    opt.trace.max_depth = st.depth;
    opt.trace.tree_depth = st.tree_depth;
    opt.trace.gradient_depth = st.gradient_depth;
    opt.samples_per_axis = 2;
    dr::RoundingSensitivity r;
    const double seconds =
        dt_bench::best_seconds([&] { r = dr::rounding_sensitivity(s, cam, opt, adjoint.data()); });
    std::printf("{\"size\": %d, \"depth\": %d, \"tree_depth\": %d, \"gradient_depth\": %d, \"pixels_moved\": %.6f,"
                " \"dIoR_pixels_moved\": %.6f, \"ior_moved\": %.4g, \"positions_moved\": %.4g,"
                " \"absorption_moved\": %.4g, \"environment_moved\": %.4g, \"seconds\": %.2f}\n",
                size, st.depth, st.tree_depth, st.gradient_depth, r.image_share, r.derivative_share, r.ior,
                r.positions, r.absorption, r.environment, seconds);
    std::fflush(stdout);
  }
  return 0;
}
