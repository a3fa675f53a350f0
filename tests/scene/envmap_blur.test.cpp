// Equirectangular blur: σ <= 0 copies, energy is kept in each row's
// longitude (wrap) and a lone texel spreads symmetrically across the seam.
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "difftrans/scene/envmap_blur.hpp"

namespace sc = difftrans::scene;

TEST_CASE("envmap blur: copy at sigma 0, a texel on the seam spreads both ways, sums kept per row") {
  const int w = 16, h = 32;
  std::vector<float> t(std::size_t(w) * h * 3, 0.0f);
  t[(std::size_t(16) * w + 0) * 3 + 1] = 1.0f;  // green texel on the seam, row 16
  CHECK(sc::blur_equirect(t, w, h, 0.0f) == t);
  const std::vector<float> b = sc::blur_equirect(t, w, h, 1.5f);
  const auto at = [&](int x, int y) { return b[(std::size_t(y) * w + x) * 3 + 1]; };
  CHECK(at(1, 16) == doctest::Approx(at(w - 1, 16)));  // across the seam
  CHECK(at(0, 16) > at(1, 16));
  CHECK(at(0, 15) == doctest::Approx(at(0, 17)));
  double sum = 0.0;
  for (float v : b) sum += v;
  CHECK(sum == doctest::Approx(1.0).epsilon(1e-4));  // away from the poles nothing is lost
  CHECK(b[(std::size_t(16) * w + 0) * 3 + 0] == 0.0f);  // channels stay apart
}
