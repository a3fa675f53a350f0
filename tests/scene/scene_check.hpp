// Test helpers for the scene layer: a reader over double-precision parameter
// arrays that hands out one chosen parameter as the scalar under test (so the
// generic code can be differentiated with ad_check's derivative() and finite
// differences in double), and a forward-versus-reverse check with the
// library's own ParamReaders.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "support/ad_check.hpp"
#include "difftrans/scene/scene.hpp"

namespace dt_test {

// Reads buffer b, entry i as S(values[b][i]), except the one (buffer, index)
// that returns x (every read of it: the same variable).
template <class S>
struct OverrideReader {
  const std::vector<std::vector<double>>* values;
  int buffer = -1;
  std::int32_t index = -1;
  S x{};
  S read(int b, std::int32_t i) const {
    if (b == buffer && i == index) return x;
    return S((*values)[std::size_t(b)][std::size_t(i)]);
  }
};

// d f(reader) / d values[b][i] with scalar S (f returns one S).
template <class S, class F>
double param_derivative(const std::vector<std::vector<double>>& values, int b, std::int32_t i, F&& f,
                        double* value = nullptr) {
  return derivative<S>(
      [&](auto x) {
        OverrideReader<decltype(x)> r{&values, b, i, x};
        return f(r);
      },
      values[std::size_t(b)][std::size_t(i)], value);
}

// The same derivative by central differences in double.
template <class F>
double param_difference(const std::vector<std::vector<double>>& values, int b, std::int32_t i, F&& f,
                        double h = 1e-6) {
  return central_difference(
      [&](double x) {
        OverrideReader<double> r{&values, b, i, x};
        return f(r);
      },
      values[std::size_t(b)][std::size_t(i)], h);
}

inline std::vector<double> uniform_values(std::size_t n, double lo, double hi, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

inline std::vector<float> to_float(const std::vector<double>& v) { return std::vector<float>(v.begin(), v.end()); }

// The library's readers on one float buffer: the gradient from the reverse
// pass (Var<double>, leaves scattered into the buffer's gradient) dotted with
// L random tangents equals the forward pass (Dual<double, L>) lane by lane;
// float, double, Dual and Var give the same value. f(reader) returns one
// scalar. Returns the reverse-mode gradient.
template <class F>
std::vector<double> check_forward_vs_reverse(const std::vector<float>& values, int buffer, F&& f,
                                             double rel = 1e-5) {
  constexpr int L = 4;
  std::vector<float> grad(values.size(), 0.0f);
  std::vector<float> tangents[L];
  for (int l = 0; l < L; ++l) tangents[l] = to_float(uniform_values(values.size(), -1.0, 1.0, 100u + unsigned(l)));
  ad::ParamSet set;
  ad::ParamBuffer& b = set.buffers[buffer];
  b.values = values.data();
  b.size = std::int32_t(values.size());
  b.gradient = grad.data();
  for (int l = 0; l < L; ++l) b.tangents[l] = tangents[l].data();

  ad::Tape<double> tape(1 << 18);
  std::vector<ad::LeafRecord> log(1 << 16);
  ad::ParamReader<ad::Var<double>> rev(&set, &tape, log.data(), std::int32_t(log.size()));
  const ad::Var<double> y = f(rev);
  REQUIRE_FALSE(tape.overflowed());
  REQUIRE_FALSE(rev.overflowed());
  tape.backward(y);
  rev.scatter();

  ad::ParamReader<ad::Dual<double, L>> fwd(&set);
  const ad::Dual<double, L> yd = f(fwd);
  ad::ParamReader<double> plain(&set);
  const double yp = f(plain);
  CHECK(yd.value == y.value);
  CHECK(yp == y.value);
  ad::ParamReader<float> plain_f(&set);
  CHECK(close(double(f(plain_f)), yp, 1e-4));

  std::vector<double> g(grad.begin(), grad.end());
  for (int l = 0; l < L; ++l) {
    double dot = 0.0, scale = 0.0;
    for (std::size_t i = 0; i < g.size(); ++i) {
      dot += g[i] * double(tangents[l][i]);
      scale += std::abs(g[i] * double(tangents[l][i]));
    }
    CAPTURE(l);
    CHECK(std::abs(double(yd.grad[l]) - dot) <= rel * std::max(1.0, scale));
  }
  return g;
}

}  // namespace dt_test
