// Forward mode: layout, construction, lanes as Jacobian columns, mixed
// arithmetic with plain numbers.
#include "support/ad_check.hpp"

#include <cstring>

using namespace dt_test;
using ad::Dual;

static_assert(std::is_trivially_copyable_v<Dual<float, 1>>);
static_assert(std::is_trivially_copyable_v<Dual<double, 8>>);
static_assert(std::is_trivially_default_constructible_v<Dual<float, 4>>);
static_assert(sizeof(Dual<float, 1>) == 2 * sizeof(float));
static_assert(sizeof(Dual<float, 8>) == 9 * sizeof(float));

TEST_CASE("construction from numbers gives zero tangents") {
  const Dual<float, 3> a(2.0);  // from double
  const Dual<float, 3> b = 7;   // from int
  CHECK(a.value == 2.0f);
  CHECK(b.value == 7.0f);
  for (int i = 0; i < 3; ++i) CHECK((a.grad[i] == 0.0f && b.grad[i] == 0.0f));
  const Dual<double, 2> v = Dual<double, 2>::variable(1.5, 1);
  CHECK(v.grad[0] == 0.0);
  CHECK(v.grad[1] == 1.0);
  Dual<double, 2> copy;
  std::memcpy(&copy, &v, sizeof v);  // trivially copyable: bytes are the value
  CHECK(copy.grad[1] == 1.0);
}

TEST_CASE("lanes carry independent directions: a Jacobian in one pass") {
  using D = Dual<double, 2>;
  const D x = D::variable(0.5, 0), y = D::variable(-2.0, 1);
  // f(x, y) = (x y², sin(x) + y)
  const D f0 = x * y * y;
  const D f1 = sin(x) + y;
  CHECK(f0.grad[0] == doctest::Approx(4.0));   // y²
  CHECK(f0.grad[1] == doctest::Approx(-2.0));  // 2xy
  CHECK(f1.grad[0] == doctest::Approx(std::cos(0.5)));
  CHECK(f1.grad[1] == doctest::Approx(1.0));
}

TEST_CASE("mixed arithmetic with plain numbers on either side") {
  using D = Dual<float, 1>;
  const D x = D::variable(2.0f, 0);
  const D a = 1 + x * 2.0 - 3.0f / x;  // int, double, float constants
  CHECK(a.value == doctest::Approx(1 + 4 - 1.5));
  CHECK(a.grad[0] == doctest::Approx(2 + 3.0 / 4));
  const D b = x / 4;
  CHECK(b.grad[0] == doctest::Approx(0.25));
  CHECK((x < 3 && x > 1.5 && x == 2.0f && x != 1 && 2 <= x && x >= D(2)));
}

TEST_CASE("higher lane counts agree with one lane at a time") {
  using D8 = Dual<float, 8>;
  using D1 = Dual<float, 1>;
  const auto f = [](auto x, auto y) { return exp(x * 0.3) * atan2(y, x + 2.0) + sqrt(x * x + y * y); };
  D8 x8 = D8::variable(0.4f, 0), y8 = D8::variable(1.1f, 5);
  const D8 r8 = f(x8, y8);
  const D1 rx = f(D1::variable(0.4f, 0), D1(1.1f));
  const D1 ry = f(D1(0.4f), D1::variable(1.1f, 0));
  CHECK(r8.grad[0] == doctest::Approx(rx.grad[0]));
  CHECK(r8.grad[5] == doctest::Approx(ry.grad[0]));
  for (int i : {1, 2, 3, 4, 6, 7}) CHECK(r8.grad[i] == 0.0f);
}
