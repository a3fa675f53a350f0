// The device-path optics kernel, run on the host: float, Dual and Var give
// the same values, and Dual and Var the same gradients, which agree with
// central finite differences in double.
#include "support/ad_check.hpp"

#include "support/optics_probe.hpp"

using namespace dt_test;
using dt_test::OpticsItem;
using dt_test::OpticsResult;

namespace {
double probe_double(const OpticsItem& it, double eta, const double sigma[3]) {
  return dt_test::optics_probe(it, eta, Vec3d(sigma[0], sigma[1], sigma[2]));
}
}  // namespace

TEST_CASE("probe: every scalar agrees, gradients match finite differences") {
  const auto items = dt_test::make_optics_items(500, 7);
  ad::Tape<float> tape(dt_test::optics_probe_tape_capacity);
  int tir = 0;
  for (const OpticsItem& it : items) {
    const OpticsResult f = dt_test::optics_probe_gradient<float>(it);
    const OpticsResult d1 = dt_test::optics_probe_gradient<ad::Dual<float, 1>>(it);
    const OpticsResult d4 = dt_test::optics_probe_gradient<ad::Dual<float, 4>>(it);
    const OpticsResult v = dt_test::optics_probe_gradient<ad::Var<float>>(it, &tape);
    REQUIRE_FALSE(tape.overflowed());
    CHECK(std::isfinite(f.value));
    CHECK(d1.value == f.value);
    CHECK(d4.value == f.value);
    CHECK(v.value == f.value);
    CHECK(d1.grad[0] == d4.grad[0]);
    const double cos_i = it.wi[2];
    if (cos_i < 0 && it.eta * std::sqrt(1 - cos_i * cos_i) >= 1) ++tir;
    const double sigma[3] = {it.sigma[0], it.sigma[1], it.sigma[2]};
    for (int k = 0; k < 4; ++k) {
      CAPTURE(k);
      CAPTURE(it.eta);
      CAPTURE(cos_i);
      CHECK(std::isfinite(v.grad[k]));
      CHECK(close(v.grad[k], d4.grad[k], 1e-5));
      const double fd = central_difference(
          [&](double t) {
            double e = it.eta, s[3] = {sigma[0], sigma[1], sigma[2]};
            (k == 0 ? e : s[k - 1]) = t;
            return probe_double(it, e, s);
          },
          k == 0 ? double(it.eta) : sigma[k - 1], 1e-7);
      CHECK(close(v.grad[k], fd, 2e-3));
    }
  }
  CHECK(tir > 10);  // the input set does exercise total internal reflection
}
