// Uses the installed headers: Fresnel reflectance at normal incidence and its
// derivative along the IoR, in forward and reverse mode.
#include <difftrans/difftrans.hpp>

#include <cmath>
#include <cstdio>

int main() {
  namespace ad = difftrans::ad;
  const double eta = 1.5;
  const auto fd = difftrans::optics::fresnel_dielectric(1.0, ad::Dual<double, 1>::variable(eta, 0));
  ad::Tape<double> tape(64);
  const ad::Var<double> e = tape.variable(eta);
  const auto fv = difftrans::optics::fresnel_dielectric(1.0, e);
  tape.backward(fv.R);
  const double expected = 4 * (eta - 1) / std::pow(eta + 1, 3);  // d/dη ((η−1)/(η+1))²
  std::printf("R = %.6f, dR/deta = %.6f (dual) %.6f (tape) %.6f (closed form)\n", ad::value_of(fv.R),
              fd.R.grad[0], tape.adjoint(e), expected);
  return std::abs(fd.R.grad[0] - expected) < 1e-12 && std::abs(tape.adjoint(e) - expected) < 1e-12 ? 0 : 1;
}
