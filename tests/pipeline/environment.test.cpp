// Background observations for the environment fit: the margin around the
// mask, frames without masks, and the round trip — a frame rendered from a
// known environment, fitted back, compared on its background pixels.
#include "support/ad_check.hpp"

#include "pipeline/environment.hpp"

using namespace dt_test;
namespace dr = difftrans::render;
namespace pipeline = difftrans::pipeline;
namespace sc = difftrans::scene;
namespace io = difftrans::io;

namespace {
// A frame looking down −Z with a square "object" in the middle of its mask;
// its pixels show `env` everywhere (the object is not rendered: only the
// background matters here).
io::Frame frame_of(const sc::EnvMap& env, const Vec3f& dir, int size, int square) {
  io::Frame f;
  f.name = "view";
  const auto cam = sc::protocol_camera(dir, size, size);
  f.camera_to_world = Mat4<double>(cam.camera_to_world);
  f.intrinsics.fx = cam.fx;
  f.intrinsics.fy = cam.fy;
  f.intrinsics.cx = cam.cx;
  f.intrinsics.cy = cam.cy;
  f.intrinsics.width = size;
  f.intrinsics.height = size;
  f.image = io::Image(size, size);
  f.mask = io::Mask(size, size);
  ad::ParamReader<float> reader(nullptr);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      f.image.set(x, y, sc::lookup(reader, env, cam.generate_ray(x, y).direction));
      const bool inside = std::abs(x - size / 2) < square && std::abs(y - size / 2) < square;
      f.mask.inside[std::size_t(y) * size + x] = inside;
    }
  return f;
}

std::vector<float> sky(int W, int H) {
  std::vector<float> t;
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) t.insert(t.end(), {0.3f + 0.2f * std::sin(0.5f * c), 0.4f + 0.02f * r, 0.5f});
  return t;
}
}  // namespace

TEST_CASE("the margin keeps observations away from the mask") {
  const auto texels = sky(16, 8);
  const sc::EnvMap env = sc::equirect_environment(texels.data(), 16, 8);
  const io::Frame f = frame_of(env, Vec3f(0, 0, 1), 32, 4);  // mask: 7 x 7 pixels
  for (int margin : {0, 1, 3}) {
    const io::Mask bg = pipeline::background_mask(f, margin);
    const int side = 7 + 2 * margin;
    CHECK(bg.count() == std::size_t(32 * 32 - side * side));
  }
  io::Split split;
  split.frames.push_back(f);
  io::Frame no_mask = f;
  no_mask.name = "unmasked";
  no_mask.mask = io::Mask();
  split.frames.push_back(no_mask);
  io::Frame env_only = no_mask;
  env_only.name = "sky";
  env_only.environment_only = true;
  split.frames.push_back(env_only);
  std::vector<std::string> skipped;
  pipeline::BackgroundOptions opt;
  opt.margin = 1;
  const auto obs = pipeline::background_observations(split, opt, &skipped);
  CHECK(skipped == std::vector<std::string>{"unmasked"});
  CHECK(obs.size() == std::size_t(32 * 32 - 81 + 32 * 32));
}

TEST_CASE("a fitted environment reproduces the background it was fitted to") {
  const int W = 32, H = 16;
  const auto texels = sky(W, H);
  const sc::EnvMap env = sc::equirect_environment(texels.data(), W, H);
  io::Split train, test;
  for (const Vec3f& d : {Vec3f(0, 0, 1), Vec3f(1, 0.3f, 0), Vec3f(0, 0.5f, -1), Vec3f(-1, 0.1f, 0.2f)})
    train.frames.push_back(frame_of(env, d, 48, 5));
  test.frames.push_back(frame_of(env, Vec3f(0.7f, 0.2f, 0.7f), 48, 5));
  sc::EnvFitOptions opt;
  opt.width = W;
  opt.height = H;
  opt.smoothness = 1e-6;
  const sc::EnvFit fit = sc::fit_environment(pipeline::background_observations(train), opt);
  const sc::EnvMap fitted = sc::equirect_environment(fit.texels.data(), W, H);
  const double psnr_train = pipeline::background_psnr(train, fitted);
  CHECK(psnr_train > 45);  // the data is explained almost exactly (8-bit tone mapping limits PSNR)
  // a held-out view sees partly unseen directions: worse, but finite
  const double psnr_test = pipeline::background_psnr(test, fitted);
  CHECK(std::isfinite(psnr_test));
  CHECK(psnr_test < psnr_train + 1e-9);
  // against a constant map, the fit is much better
  const float grey[3] = {0.4f, 0.45f, 0.5f};
  CHECK(pipeline::background_psnr(train, sc::constant_environment(grey)) < psnr_train - 10);
}
