// Uses the installed difftrans::eigen: the uniform Laplacian of a triangle
// and the energy of a displacement field on it (Σ over edges |x_i − x_j|²).
#include <difftrans/optim/large_steps.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

int main() {
  const std::vector<std::int32_t> triangle = {0, 1, 2};
  const auto L = difftrans::optim::uniform_laplacian(triangle.data(), 1, 3);
  const std::vector<float> x = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const double energy = difftrans::optim::laplacian_energy(L, x.data());
  std::printf("Laplacian energy of the unit right triangle: %.6f (expected 4)\n", energy);
  return std::abs(energy - 4.0) < 1e-12 ? 0 : 1;
}
