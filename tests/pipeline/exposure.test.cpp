// Exposure of LDR photographs: frames showing a known environment at a known
// scale, 8-bit quantized and clipped like a photograph, give that scale back
// (median of background ratios); clipped and dark pixels are left out;
// apply_exposure divides it out.
#include "support/ad_check.hpp"

#include <cmath>
#include <cstdint>
#include <vector>

#include "pipeline/exposure.hpp"

using namespace dt_test;
namespace dr = difftrans::render;
namespace pipeline = difftrans::pipeline;
namespace sc = difftrans::scene;
namespace io = difftrans::io;

namespace {

// A frame looking along `dir` at a square "object" (masked, its pixels
// white); the background shows `scale` times the environment, stored as
// 8-bit sRGB (clamped) and decoded, as a PNG would be.
io::Frame photo(const sc::EnvMap& env, const Vec3f& dir, int size, double scale) {
  io::Frame f;
  f.name = "view";
  const auto cam = sc::protocol_camera(dir, size, size);
  f.camera_to_world = Mat4<double>(cam.camera_to_world);
  f.intrinsics = {size, size, cam.fx, cam.fy, cam.cx, cam.cy};
  io::Image linear(size, size);
  f.mask = io::Mask(size, size);
  ad::ParamReader<float> reader(nullptr);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const bool inside = std::abs(x - size / 2) < size / 6 && std::abs(y - size / 2) < size / 6;
      f.mask.inside[std::size_t(y) * size + x] = inside;
      const Vec3f c = inside ? Vec3f(5.0f) : sc::lookup(reader, env, cam.generate_ray(x, y).direction) * float(scale);
      linear.set(x, y, c);
    }
  const auto bytes = io::tone_map(linear);
  f.image = io::from_srgb8(bytes.data(), size, size, 3);
  return f;
}

// A sky with texture and a bright band (which clips at scale 2).
std::vector<float> sky(int W, int H) {
  std::vector<float> t;
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      const float band = (r == H / 2 || r == H / 2 - 1) ? 0.5f : 0.0f;
      t.insert(t.end(), {0.15f + 0.1f * std::sin(0.7f * float(c)) + band, 0.25f + 0.01f * float(r) + band, 0.3f + band});
    }
  return t;
}

}  // namespace

TEST_CASE("the exposure of 8-bit photographs of a known environment is recovered") {
  const auto texels = sky(32, 16);
  const sc::EnvMap env = sc::equirect_environment(texels.data(), 32, 16);
  for (double scale : {0.5, 1.0, 2.0}) {
    io::Split split;
    for (const Vec3f dir : {Vec3f(0, 0, 1), Vec3f(1, 0.3f, 0), Vec3f(-0.5f, -0.2f, -1)})
      split.frames.push_back(photo(env, dir, 48, scale));
    const pipeline::ExposureEstimate e = pipeline::estimate_exposure(split, env);
    CAPTURE(scale);
    CHECK(e.scale == doctest::Approx(scale).epsilon(0.02));
    CHECK(e.pixels > 2000);
    CHECK(e.q25 <= e.scale);
    CHECK(e.q75 >= e.scale);
    CHECK(e.q75 / e.q25 < 1.1);  // one scale explains the background
    if (scale == 2.0) CHECK(e.clipped > 0);  // the band saturates
    else CHECK(e.clipped == 0);
    const float before = split.frames[1].image.rgb[7];
    pipeline::apply_exposure(split, e.scale);
    CHECK(split.frames[1].image.rgb[7] == doctest::Approx(before / e.scale));
  }
}

TEST_CASE("exposure: without usable pixels the scale is NaN; frames without masks are not used") {
  const auto texels = sky(32, 16);
  const sc::EnvMap env = sc::equirect_environment(texels.data(), 32, 16);
  io::Split split;
  split.frames.push_back(photo(env, Vec3f(0, 0, 1), 24, 1.0));
  split.frames[0].mask = io::Mask();
  CHECK(std::isnan(pipeline::estimate_exposure(split, env).scale));
  // a black photograph: every pixel too dark
  io::Split dark;
  dark.frames.push_back(photo(env, Vec3f(0, 0, 1), 24, 1e-4));
  const pipeline::ExposureEstimate e = pipeline::estimate_exposure(dark, env);
  CHECK(e.pixels == 0);
  CHECK(e.dark > 0);
  CHECK(std::isnan(e.scale));
}
