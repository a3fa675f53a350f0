// How far the host passes move when only the rounding changes: the same view
// rendered again from an eye moved by one float step (along x, then along
// y), which changes the last bits of every camera ray and nothing else.
// A pass whose result moves by more than a tolerance here cannot be expected
// to agree that closely with another implementation (the device, another
// compiler's contractions) either; a gradient that moves by its own size is
// carried by a few chaotic rays and is noise to an optimizer.
// bench/conditioning.cpp prints it over depths; tests/render and
// tests/cuda use it to say what agreement is possible.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "difftrans/render/passes.hpp"
#include "difftrans/scene/camera.hpp"

namespace difftrans::render {

// The camera with its eye moved by one float step along world axis `axis`
// (0, 1, 2): the next float towards +infinity.
inline scene::Camera moved_eye(scene::Camera cam, int axis) {
  float& c = cam.camera_to_world[3][axis];
  c = std::nextafter(c, 3.4e38f);
  cam.world_to_camera = glm::inverse(cam.camera_to_world);
  return cam;
}

// What moves, as the larger of the two moves (x and y).
struct RoundingSensitivity {
  double image_share = 0;       // share of pixels with a value moved by > 1e-4 · max(1, |value|)
  double derivative_share = 0;  // share of pixels with d/dIoR moved by > 1e-3 · max(rms, |d|)
  // |g_moved − g| / |g| per gradient buffer (0 where |g| = 0)
  double ior = 0, positions = 0, absorption = 0, environment = 0;
};

namespace detail {

// Share of pixels (RGB triples) where a and b differ by more than tol · max(floor, |b|).
inline double moved_share(const std::vector<float>& a, const std::vector<float>& b, double tol, double floor) {
  std::size_t moved = 0;
  for (std::size_t p = 0; p + 2 < a.size(); p += 3) {
    bool m = false;
    for (int k = 0; k < 3; ++k) {
      const double d = std::abs(double(a[p + std::size_t(k)]) - double(b[p + std::size_t(k)]));
      m = m || !(d <= tol * std::max(floor, std::abs(double(b[p + std::size_t(k)]))));
    }
    moved += m;
  }
  return a.empty() ? 0.0 : double(moved) / double(a.size() / 3);
}

inline double relative_change(const std::vector<float>& moved, const std::vector<float>& base) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < base.size(); ++i) {
    num += (double(moved[i]) - base[i]) * (double(moved[i]) - base[i]);
    den += double(base[i]) * base[i];
  }
  return den > 0 ? std::sqrt(num / den) : 0.0;
}

}  // namespace detail

// The image, the derivative image along the IoR and the gradient of
// Σ adjoint · image (adjoint: width·height·3) from the camera's eye and from
// the two moved eyes.
inline RoundingSensitivity rounding_sensitivity(const HostScene& s, const scene::Camera& cam, const PassOptions& opt,
                                                const float* adjoint) {
  const float one = 1.0f;
  const float* ior_only[param_count] = {nullptr, &one, nullptr, nullptr};
  const std::vector<float> image = render_image(s, cam, opt);
  const ImageDerivative d = render_derivative(s, cam, ior_only, opt);
  SceneGradient g(s);
  render_gradient(s, cam, adjoint, g, opt);
  double rms = 0;
  for (float x : d.derivative) rms += double(x) * x;
  rms = std::sqrt(rms / double(std::max<std::size_t>(d.derivative.size(), 1)));
  RoundingSensitivity r;
  for (int axis = 0; axis < 2; ++axis) {
    const scene::Camera moved = moved_eye(cam, axis);
    r.image_share = std::max(r.image_share, detail::moved_share(render_image(s, moved, opt), image, 1e-4, 1.0));
    const ImageDerivative dm = render_derivative(s, moved, ior_only, opt);
    r.derivative_share = std::max(r.derivative_share, detail::moved_share(dm.derivative, d.derivative, 1e-3, rms));
    SceneGradient gm(s);
    render_gradient(s, moved, adjoint, gm, opt);
    r.ior = std::max(r.ior, detail::relative_change(gm.ior, g.ior));
    r.positions = std::max(r.positions, detail::relative_change(gm.positions, g.positions));
    r.absorption = std::max(r.absorption, detail::relative_change(gm.absorption, g.absorption));
    r.environment = std::max(r.environment, detail::relative_change(gm.environment, g.environment));
  }
  return r;
}

}  // namespace difftrans::render
