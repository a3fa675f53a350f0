// Every derivative rule of ad/math.hpp, in forward and reverse mode, against
// its closed form and against central finite differences in double; the
// non-smooth points get the defined, finite derivatives the header documents.
#include "support/ad_check.hpp"

using namespace dt_test;

namespace {


template <class S, class F, class DF>
void check_rule(const char* name, F f, DF df, std::initializer_list<double> points) {
  for (double x : points) {
    CAPTURE(name);
    CAPTURE(x);
    double value = 0;
    const double d = derivative<S>(f, x, &value);
    const double closed = df(x);
    const double fd = central_difference([&](double t) { return f(t); }, x);
    CHECK(close(value, double(f(x)), tol<S>()));
    CHECK(close(d, closed, tol<S>() * 10));
    CHECK(close(closed, fd, 1e-6));  // the closed form itself is right
  }
}

}  // namespace

TEST_CASE_TEMPLATE("derivative rules match closed forms and finite differences", S, DT_AD_SCALARS) {
  // binary operators, with AD on both sides and on either side alone
  check_rule<S>("a+b", [](auto x) { return x + x * x; }, [](double x) { return 1 + 2 * x; }, {-2.0, 0.0, 3.5});
  check_rule<S>("a-b", [](auto x) { return 3.0 - x - x * x; }, [](double x) { return -1 - 2 * x; }, {-2.0, 0.0, 3.5});
  check_rule<S>("a*b", [](auto x) { return x * (x + 1.0) * 2; }, [](double x) { return 4 * x + 2; }, {-2.0, 0.0, 3.5});
  check_rule<S>("a/b", [](auto x) { return (x + 2.0) / (x * x + 1.0); },
                [](double x) { return (1 * (x * x + 1) - (x + 2) * 2 * x) / ((x * x + 1) * (x * x + 1)); },
                {-2.0, 0.0, 3.5});
  check_rule<S>("c/b", [](auto x) { return 2.0 / x; }, [](double x) { return -2.0 / (x * x); }, {-2.0, 0.5, 3.5});
  check_rule<S>("-x", [](auto x) { return -x; }, [](double) { return -1.0; }, {-1.0, 2.0});
  check_rule<S>("compound", [](auto x) { auto y = x; y += x; y *= x; y -= 1.0; y /= 2.0; return y; },
                [](double x) { return 2 * x; }, {-1.0, 2.0});
  // functions
  check_rule<S>("sqrt", [](auto x) { return sqrt(x); }, [](double x) { return 0.5 / std::sqrt(x); }, {0.01, 1.0, 7.0});
  check_rule<S>("safe_sqrt", [](auto x) { return safe_sqrt(x); }, [](double x) { return 0.5 / std::sqrt(x); }, {0.01, 1.0, 7.0});
  check_rule<S>("square", [](auto x) { return square(x); }, [](double x) { return 2 * x; }, {-3.0, 0.0, 2.0});
  check_rule<S>("exp", [](auto x) { return exp(x); }, [](double x) { return std::exp(x); }, {-3.0, 0.0, 2.0});
  check_rule<S>("expm1", [](auto x) { return expm1(x); }, [](double x) { return std::exp(x); }, {-3.0, 1e-3, 2.0});
  check_rule<S>("log", [](auto x) { return log(x); }, [](double x) { return 1 / x; }, {0.1, 1.0, 9.0});
  check_rule<S>("log1p", [](auto x) { return log1p(x); }, [](double x) { return 1 / (1 + x); }, {-0.5, 1e-3, 9.0});
  check_rule<S>("sin", [](auto x) { return sin(x); }, [](double x) { return std::cos(x); }, {-2.0, 0.0, 1.0});
  check_rule<S>("cos", [](auto x) { return cos(x); }, [](double x) { return -std::sin(x); }, {-2.0, 0.0, 1.0});
  check_rule<S>("tan", [](auto x) { return tan(x); }, [](double x) { return 1 / (std::cos(x) * std::cos(x)); }, {-1.0, 0.0, 1.2});
  check_rule<S>("asin", [](auto x) { return asin(x); }, [](double x) { return 1 / std::sqrt(1 - x * x); }, {-0.9, 0.0, 0.5});
  check_rule<S>("acos", [](auto x) { return acos(x); }, [](double x) { return -1 / std::sqrt(1 - x * x); }, {-0.9, 0.0, 0.5});
  check_rule<S>("atan", [](auto x) { return atan(x); }, [](double x) { return 1 / (1 + x * x); }, {-4.0, 0.0, 0.5});
  check_rule<S>("tanh", [](auto x) { return tanh(x); }, [](double x) { return 1 - std::tanh(x) * std::tanh(x); }, {-2.0, 0.0, 0.5});
  check_rule<S>("sigmoid", [](auto x) { return sigmoid(x); },
                [](double x) { const double s = 1 / (1 + std::exp(-x)); return s * (1 - s); }, {-30.0, -2.0, 0.0, 3.0, 30.0});
  check_rule<S>("softplus", [](auto x) { return softplus(x); }, [](double x) { return 1 / (1 + std::exp(-x)); },
                {-30.0, -2.0, 0.0, 3.0, 30.0});
  check_rule<S>("abs", [](auto x) { return abs(x); }, [](double x) { return x > 0 ? 1.0 : -1.0; }, {-2.0, 0.5});
  check_rule<S>("pow(x,c)", [](auto x) { return pow(x, 2.5); }, [](double x) { return 2.5 * std::pow(x, 1.5); }, {0.5, 1.0, 3.0});
  check_rule<S>("pow(c,x)", [](auto x) { return pow(1.7, x); }, [](double x) { return std::log(1.7) * std::pow(1.7, x); }, {-1.0, 0.0, 3.0});
  check_rule<S>("pow(x,x)", [](auto x) { return pow(x, x); },
                [](double x) { return std::pow(x, x) * (std::log(x) + 1); }, {0.5, 1.0, 2.0});
  check_rule<S>("atan2(x,c)", [](auto x) { return atan2(x, 0.7); }, [](double x) { return 0.7 / (0.49 + x * x); }, {-2.0, 0.0, 1.0});
  check_rule<S>("atan2(c,x)", [](auto x) { return atan2(0.7, x); }, [](double x) { return -0.7 / (0.49 + x * x); }, {-2.0, 0.3, 1.0});
  check_rule<S>("atan2(x,x²)", [](auto x) { return atan2(x, x * x); },
                [](double x) { return (x * x - x * 2 * x) / (x * x * x * x + x * x); }, {-2.0, 0.3, 1.0});
  check_rule<S>("min", [](auto x) { return min(x, 1.0 - x); }, [](double x) { return x < 1 - x ? 1.0 : -1.0; }, {0.2, 0.8});
  check_rule<S>("max", [](auto x) { return max(x, 1.0 - x); }, [](double x) { return x > 1 - x ? 1.0 : -1.0; }, {0.2, 0.8});
  check_rule<S>("clamp", [](auto x) { return clamp(3.0 * x, -1.0, 1.0); },
                [](double x) { return std::abs(3 * x) < 1 ? 3.0 : 0.0; }, {-2.0, 0.1, 2.0});
  check_rule<S>("select", [](auto x) { return select(x > 0, x * x, -x); },
                [](double x) { return x > 0 ? 2 * x : -1.0; }, {-2.0, 0.5});
}

TEST_CASE_TEMPLATE("non-smooth points have defined, finite derivatives", S, DT_AD_SCALARS) {
  // safe_sqrt: finite at 0 and below, value clamps to 0
  double v = -1;
  double d = derivative<S>([](auto x) { return safe_sqrt(x); }, 0.0, &v);
  CHECK(v == 0.0);
  CHECK(std::isfinite(d));
  CHECK(d > 0);
  d = derivative<S>([](auto x) { return safe_sqrt(x); }, -1.0, &v);
  CHECK(v == 0.0);
  CHECK(std::isfinite(d));
  // plain sqrt keeps its true, infinite slope at 0
  d = derivative<S>([](auto x) { return sqrt(x); }, 0.0);
  CHECK(std::isinf(d));
  // abs: sign(0) = 0
  CHECK(derivative<S>([](auto x) { return abs(x); }, 0.0) == 0.0);
  // asin / acos at ±1: finite
  for (double x : {-1.0, 1.0}) {
    CHECK(std::isfinite(derivative<S>([](auto t) { return asin(t); }, x)));
    CHECK(std::isfinite(derivative<S>([](auto t) { return acos(t); }, x)));
  }
  // pow at x = 0: the log term is dropped, x^0 is flat
  CHECK(derivative<S>([](auto x) { return pow(0.0, x); }, 2.0) == 0.0);
  CHECK(derivative<S>([](auto x) { return pow(x, 0.0); }, 0.0) == 0.0);
  CHECK(derivative<S>([](auto x) { return pow(x, 2.0); }, 0.0) == 0.0);
  // atan2 at the origin: 0
  CHECK(derivative<S>([](auto x) { return atan2(x, x); }, 0.0) == 0.0);
  // ties in min/max pick the first argument; clamp at the bounds passes dx
  CHECK(derivative<S>([](auto x) { return min(2.0 * x, 1.0); }, 0.5) == 2.0);
  CHECK(derivative<S>([](auto x) { return max(1.0, 2.0 * x); }, 0.5) == 0.0);
  CHECK(derivative<S>([](auto x) { return clamp(x, 0.0, 1.0); }, 1.0) == 1.0);
  // sigmoid / softplus / exp far out: no overflow, no NaN
  for (double x : {-800.0, 800.0}) {
    double val = 0;
    CHECK(std::isfinite(derivative<S>([](auto t) { return sigmoid(t); }, x, &val)));
    CHECK(std::isfinite(val));
    CHECK(std::isfinite(derivative<S>([](auto t) { return softplus(t); }, x)));
  }
  CHECK(derivative<S>([](auto t) { return exp(t); }, -800.0) == 0.0);
}

TEST_CASE("forward, reverse and finite differences agree on composite functions") {
  // f(x, y, z): a tangle of every kind of rule.
  const auto f = [](auto x, auto y, auto z) {
    const auto a = sqrt(x * x + y * y + 1.0) * exp(-0.3 * z);
    const auto b = atan2(y, x) + log1p(z * z) / (1.0 + sigmoid(x - y));
    const auto c = pow(abs(z) + 0.5, y) * tanh(b) - softplus(a - b);
    return min(a * b + c, 10.0 + cos(x)) + clamp(sin(z) * a, -0.5, 0.5);
  };
  const double p[3] = {0.7, -1.3, 0.4};
  // forward mode: one Dual with three lanes gives the whole gradient
  using D = ad::Dual<double, 3>;
  const D yd = f(D::variable(p[0], 0), D::variable(p[1], 1), D::variable(p[2], 2));
  // reverse mode
  ad::Tape<double> tape(512);
  const auto x = tape.variable(p[0]), y = tape.variable(p[1]), z = tape.variable(p[2]);
  const auto yv = f(x, y, z);
  REQUIRE(tape.backward(yv));
  const double g[3] = {tape.adjoint(x), tape.adjoint(y), tape.adjoint(z)};
  CHECK(yd.value == doctest::Approx(yv.value).epsilon(1e-15));
  for (int i = 0; i < 3; ++i) {
    CAPTURE(i);
    double q[3] = {p[0], p[1], p[2]};
    const double fd = central_difference(
        [&](double t) {
          q[i] = t;
          return f(q[0], q[1], q[2]);
        },
        p[i]);
    CHECK(close(yd.grad[i], g[i], 1e-12));
    CHECK(close(yd.grad[i], fd, 1e-7));
  }
  // float scalars agree with double to float precision
  using Df = ad::Dual<float, 3>;
  const Df yf = f(Df::variable(float(p[0]), 0), Df::variable(float(p[1]), 1), Df::variable(float(p[2]), 2));
  for (int i = 0; i < 3; ++i) CHECK(close(yf.grad[i], yd.grad[i], 1e-4));
}

TEST_CASE_TEMPLATE("plain scalars use the same names", T, float, double) {
  CHECK(difftrans::sqrt(T(4)) == T(2));
  CHECK(difftrans::safe_sqrt(T(-1)) == T(0));
  CHECK(difftrans::sigmoid(T(0)) == T(0.5));
  CHECK(difftrans::softplus(T(0)) == doctest::Approx(std::log(2.0)));
  CHECK(difftrans::softplus(T(1000)) == T(1000));
  CHECK(difftrans::sigmoid(T(-1000)) == T(0));
  CHECK(difftrans::clamp(T(3), T(0), T(1)) == T(1));
  CHECK(difftrans::select(true, T(1), T(2)) == T(1));
  CHECK(difftrans::min(T(1), T(2)) == T(1));
  CHECK(difftrans::max(T(1), 2) == T(2));
  static_assert(std::is_same_v<decltype(difftrans::sqrt(T(4))), T>);
  static_assert(std::is_same_v<decltype(difftrans::exp(T(4))), T>);
}
