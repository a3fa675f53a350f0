// Reverse mode: recording, backward, adjoints, reset and checkpoints,
// caller-owned buffers, vector-Jacobian products, and overflow that is
// reported rather than silent.
#include "support/ad_check.hpp"

using namespace dt_test;
using ad::Tape;
using ad::Var;

TEST_CASE("backward gives the gradient; constants record nothing") {
  Tape<double> tape(64);
  const Var<double> x = tape.variable(3.0), y = tape.variable(-2.0);
  const int before = tape.size();
  const Var<double> c = Var<double>(2.0) * Var<double>(5.0);  // constant expression
  CHECK(c.is_constant());
  CHECK(tape.size() == before);
  const Var<double> f = x * y + c * x;  // df/dx = y + 10, df/dy = x
  CHECK(tape.size() == before + 3);
  REQUIRE(tape.backward(f));
  CHECK(tape.adjoint(x) == 8.0);
  CHECK(tape.adjoint(y) == 3.0);
  CHECK(tape.adjoint(c) == 0.0);
  // a second backward from another output restarts from zero adjoints
  const Var<double> g = x * x;
  tape.backward(g);
  CHECK(tape.adjoint(x) == 6.0);
  CHECK(tape.adjoint(y) == 0.0);
}

TEST_CASE("reset and rewind make one tape serve one work item after another") {
  Tape<float> tape(32);
  const Var<float> eta = tape.variable(1.5f);  // shared leaf, recorded once
  const int mark = tape.mark();
  for (int ray = 0; ray < 100; ++ray) {
    tape.rewind(mark);
    const Var<float> y = eta * float(ray) + sin(eta);
    REQUIRE(tape.backward(y));
    CHECK(tape.adjoint(eta) == doctest::Approx(ray + std::cos(1.5)));
    CHECK(tape.size() == mark + 3);
  }
  tape.reset();
  CHECK(tape.size() == 1);
  CHECK(tape.adjoint(eta) == 0.0f);  // forgotten: eta's node is gone
}

TEST_CASE("caller-owned storage, as in a device kernel") {
  ad::Node<double> nodes[16];
  double adjoints[16];
  Tape<double> tape(nodes, adjoints, 16);
  const auto x = tape.variable(0.5);
  const auto y = exp(x) * x;
  tape.backward(y);
  CHECK(tape.adjoint(x) == doctest::Approx(std::exp(0.5) * 1.5));
  CHECK(tape.bytes_used() == std::size_t(tape.size()) * (sizeof(ad::Node<double>) + sizeof(double)));
}

TEST_CASE("vector-Jacobian product with several seeded outputs") {
  Tape<double> tape(64);
  const auto x = tape.variable(2.0), y = tape.variable(3.0);
  const auto r = x * y, g = x + y, b = x - y;  // an "RGB" output
  tape.zero_adjoints();
  tape.seed(r, 1.0);
  tape.seed(g, 10.0);
  tape.seed(b, 100.0);
  tape.propagate();
  CHECK(tape.adjoint(x) == 3.0 + 10.0 + 100.0);
  CHECK(tape.adjoint(y) == 2.0 + 10.0 - 100.0);
}

TEST_CASE("overflow is reported, never silent") {
  Tape<double> tape(8);
  auto x = tape.variable(1.0);
  auto y = x;
  for (int i = 0; i < 20; ++i) y = y * 1.1 + x;
  CHECK(tape.overflowed());
  CHECK(tape.size() == tape.capacity());
  CHECK_FALSE(tape.backward(y));
  CHECK(std::isfinite(y.value));  // values stay right; only the gradient is partial
  tape.reset();
  CHECK_FALSE(tape.overflowed());
  const auto z = tape.variable(2.0);
  CHECK(tape.backward(z * z));
  CHECK(tape.adjoint(z) == 4.0);
}

TEST_CASE("variables of another tape contribute nothing to this one") {
  Tape<double> a(16), b(16);
  const auto x = a.variable(1.0);
  const auto y = b.variable(2.0);
  b.backward(y * y);
  CHECK(b.adjoint(x) == 0.0);
  CHECK(b.adjoint(y) == 4.0);
}

TEST_CASE("tape sizes are what a per-ray budget can rely on") {
  static_assert(sizeof(ad::Node<float>) == 16);
  static_assert(sizeof(Var<float>) == 16);
  static_assert(Tape<float>::bytes_per_node == 20);
  Tape<float> tape(0);  // clamps to the sink alone
  CHECK(tape.capacity() == 1);
  const auto x = tape.variable(1.0f);
  CHECK(tape.overflowed());
  CHECK(x.index == 0);
}

TEST_CASE("a sweep in pieces: the later nodes first, cut, the slots reused, then the rest") {
  // f(x, y) = 3 x² + x y (recorded first: x², then the rest after a mark)
  Tape<double> tape(64);
  tape.zero_on_push(true);  // a streamed pass: each slot starts at zero
  const auto x = tape.variable(1.5), y = tape.variable(-2.0);
  const auto x2 = x * x;
  const std::int32_t mark = tape.mark();
  const auto f = x2 * 3.0 + x * y;
  tape.seed(f, 1.0);
  tape.propagate(tape.size() - 1, mark);  // the nodes past the mark only
  CHECK(tape.adjoint(x2) == 3.0);         // what they passed back
  CHECK(tape.adjoint(y) == 1.5);
  CHECK(tape.adjoint(x) == -2.0);         // from x y only, so far
  const std::int32_t grown = tape.size();
  tape.truncate(mark);
  CHECK(tape.size() == mark);
  CHECK(tape.peak() == grown);
  // a second piece on the reused slots: g = x² (1 + y), seeded with 2
  const auto g = x2 * (1.0 + y);
  CHECK(tape.adjoint(g) == 0.0);  // its slot was zeroed as it was recorded
  tape.seed(g, 2.0);
  tape.propagate(tape.size() - 1, mark);
  tape.truncate(mark);
  // the rest: x² and the leaves; the total is the gradient of f + 2 g
  tape.propagate(mark - 1, 1);
  CHECK(tape.adjoint(x) == doctest::Approx(6 * 1.5 + -2.0 + 2 * 2 * 1.5 * (1 - 2.0)));
  CHECK(tape.adjoint(y) == doctest::Approx(1.5 + 2 * 1.5 * 1.5));
  CHECK_FALSE(tape.overflowed());
}
