// Traits of the scalar layer: AD queries, underlying scalar, promotion of
// mixed expressions, value_of and detach.
#include "support/ad_check.hpp"

using namespace dt_test;
using ad::Dual;
using ad::Var;

static_assert(ad::is_ad_v<Dual<float, 2>> && ad::is_ad_v<Var<double>> && !ad::is_ad_v<float>);
static_assert(ad::is_dual_v<const Dual<double, 1>&> && !ad::is_dual_v<Var<double>>);
static_assert(ad::is_var_v<Var<float>> && !ad::is_var_v<Dual<float, 1>>);
static_assert(ad::is_scalar_v<float> && ad::is_scalar_v<Var<float>> && !ad::is_scalar_v<int>);
static_assert(std::is_same_v<ad::scalar_t<Dual<float, 8>>, float>);
static_assert(std::is_same_v<ad::scalar_t<Var<double>>, double>);
static_assert(std::is_same_v<ad::scalar_t<double>, double>);
static_assert(ad::dual_lanes_v<Dual<float, 8>> == 8 && ad::dual_lanes_v<Var<float>> == 0);
static_assert(std::is_same_v<ad::promote_t<Dual<float, 2>, double>, Dual<float, 2>>);
static_assert(std::is_same_v<ad::promote_t<int, Var<double>>, Var<double>>);
static_assert(std::is_same_v<ad::promote_t<float, double>, double>);
// different AD types never mix
static_assert(!ad::is_ad_pair<Dual<float, 1>, Dual<float, 2>>::value);
static_assert(!ad::is_ad_pair<Dual<float, 1>, Var<float>>::value);
static_assert(!ad::is_ad_pair<Var<float>, Var<double>>::value);
static_assert(ad::is_ad_pair<Var<float>, double>::value);

TEST_CASE_TEMPLATE("value_of and detach", S, DT_ALL_SCALARS) {
  using T = ad::scalar_t<S>;
  const S x = S(2.5);
  CHECK(ad::value_of(x) == T(2.5));
  static_assert(std::is_same_v<decltype(ad::value_of(x)), T>);
  const S y = ad::detach(x * x);
  CHECK(ad::value_of(y) == T(6.25));
}

TEST_CASE("detach cuts derivatives") {
  using D = Dual<double, 1>;
  const D x = D::variable(3.0, 0);
  const D y = x * ad::detach(x);
  CHECK(y.grad[0] == 3.0);  // d(x · const)/dx
  ad::Tape<double> tape(16);
  const auto v = tape.variable(3.0);
  const auto w = v * ad::detach(v);
  tape.backward(w);
  CHECK(tape.adjoint(v) == 3.0);
}
