// Parameter readers: plain loads, forward-mode lanes along direction
// buffers, reverse-mode leaves scattered into gradient buffers.
#include "support/ad_check.hpp"

#include <thread>

using namespace dt_test;

TEST_CASE("one generic function, three readers") {
  float x[3] = {1.0f, 2.0f, 3.0f};
  float eta[1] = {1.5f};
  float gx[3] = {0, 0, 0}, geta[1] = {0};
  float dir_x[3] = {0.0f, 1.0f, 0.0f};  // lane 0: along x[1]
  float dir_eta[1] = {1.0f};             // lane 1: along eta
  ad::ParamSet set;
  set.buffers[0].values = x;
  set.buffers[0].size = 3;
  set.buffers[0].gradient = gx;
  set.buffers[0].tangents[0] = dir_x;
  set.buffers[1].values = eta;
  set.buffers[1].size = 1;
  set.buffers[1].gradient = geta;
  set.buffers[1].tangents[1] = dir_eta;
  // f = eta * (x0 x1 + x1 x2); the generic body reads x1 twice
  const auto f = [](auto& reader) {
    const auto e = reader.read(1, 0);
    return e * (reader.read(0, 0) * reader.read(0, 1) + reader.read(0, 1) * reader.read(0, 2));
  };
  ad::ParamReader<float> plain(&set);
  CHECK(f(plain) == doctest::Approx(1.5 * (2 + 6)));
  ad::ParamReader<ad::Dual<float, 2>> fwd(&set);
  const auto d = f(fwd);
  CHECK(d.grad[0] == doctest::Approx(1.5 * (1 + 3)));  // d/dx1
  CHECK(d.grad[1] == doctest::Approx(8.0));            // d/deta
  ad::Tape<float> tape(64);
  ad::LeafRecord log[8];
  ad::ParamReader<ad::Var<float>> rev(&set, &tape, log, 8);
  const auto v = f(rev);
  CHECK(rev.size() == 5);
  tape.backward(v);
  rev.scatter();
  CHECK(gx[0] == doctest::Approx(1.5 * 2));
  CHECK(gx[1] == doctest::Approx(1.5 * 4));  // both reads of x1 add up
  CHECK(gx[2] == doctest::Approx(1.5 * 2));
  CHECK(geta[0] == doctest::Approx(8.0));
  CHECK(rev.size() == 0);
}

TEST_CASE("log overflow is reported; scatter from many threads adds up") {
  float x[1] = {2.0f}, g[1] = {0.0f};
  ad::ParamSet set;
  set.buffers[0].values = x;
  set.buffers[0].size = 1;
  set.buffers[0].gradient = g;
  {
    ad::Tape<float> tape(64);
    ad::LeafRecord log[2];
    ad::ParamReader<ad::Var<float>> rev(&set, &tape, log, 2);
    for (int i = 0; i < 3; ++i) rev.read(0, 0);
    CHECK(rev.overflowed());
    rev.clear();
    CHECK_FALSE(rev.overflowed());
  }
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&set] {
      ad::Tape<float> tape(16);
      ad::LeafRecord log[4];
      ad::ParamReader<ad::Var<float>> rev(&set, &tape, log, 4);
      for (int i = 0; i < 1000; ++i) {
        tape.reset();
        const auto v = rev.read(0, 0);
        tape.backward(v * v);  // d/dx x² = 4
        rev.scatter();
      }
    });
  for (auto& th : threads) th.join();
  CHECK(g[0] == 16000.0f);
}

TEST_CASE("scatter_from scatters the leaves read from a tape node on, and keeps the earlier ones") {
  float x[2] = {2.0f, 3.0f}, g[2] = {0.0f, 0.0f};
  ad::ParamSet set;
  set.buffers[0].values = x;
  set.buffers[0].size = 2;
  set.buffers[0].gradient = g;
  ad::Tape<float> tape(64);
  tape.zero_on_push(true);
  ad::LeafRecord log[8];
  ad::ParamReader<ad::Var<float>> rev(&set, &tape, log, 8);
  const auto a = rev.read(0, 0);
  const std::int32_t mark = tape.mark();
  const auto b = rev.read(0, 1);
  tape.seed(a * b, 1.0f);  // d/da = b = 3, d/db = a = 2
  tape.propagate(tape.size() - 1, mark);
  rev.scatter_from(mark);
  CHECK(rev.size() == 1);  // a's record stays
  CHECK(g[0] == 0.0f);
  CHECK(g[1] == 2.0f);
  tape.truncate(mark);
  tape.propagate(mark - 1, 1);
  rev.scatter_from(1);
  CHECK(rev.size() == 0);
  CHECK(g[0] == 3.0f);
}

TEST_CASE("scatter_clipped caps the gradient's norm per clip class") {
  // f = 3 x0 + 4 x1 + 12 y + 5 z: buffers 0 and 2 in class 1 (norm 13),
  // buffer 1 in class 2 (norm 4), buffer 3 in no class
  float x[2] = {1.0f, 1.0f}, y[1] = {1.0f}, z[1] = {1.0f}, w[1] = {1.0f};
  float gx[2] = {0, 0}, gy[1] = {0}, gz[1] = {0}, gw[1] = {0};
  ad::ParamSet set;
  set.buffers[0] = {x, 2, gx};
  set.buffers[1] = {w, 1, gw};
  set.buffers[2] = {y, 1, gy};
  set.buffers[3] = {z, 1, gz};
  const auto f = [](auto& reader) {
    return 3.0f * reader.read(0, 0) + 4.0f * reader.read(0, 1) + 4.0f * reader.read(1, 0) + 12.0f * reader.read(2, 0) +
           5.0f * reader.read(3, 0);
  };
  std::int8_t classes[ad::max_param_buffers] = {1, 2, 1, 0};
  const auto run = [&](float cap1, float cap2) {
    for (float* g : {gx, gx + 1, gy, gz, gw}) *g = 0.0f;
    ad::Tape<float> tape(64);
    ad::LeafRecord log[8];
    ad::ParamReader<ad::Var<float>> rev(&set, &tape, log, 8);
    tape.backward(f(rev));
    const float caps[2] = {cap1, cap2};
    return rev.scatter_clipped(classes, caps);
  };
  CHECK(run(6.5f, 0.0f) == 1);  // class 1 halved, class 2 uncapped
  CHECK(gx[0] == doctest::Approx(1.5));
  CHECK(gx[1] == doctest::Approx(2.0));
  CHECK(gy[0] == doctest::Approx(6.0));
  CHECK(gw[0] == doctest::Approx(4.0));
  CHECK(gz[0] == doctest::Approx(5.0));  // in no class: never capped
  CHECK(run(20.0f, 1.0f) == 2);          // class 1 under its cap, class 2 capped to 1
  CHECK(gx[0] == doctest::Approx(3.0));
  CHECK(gy[0] == doctest::Approx(12.0));
  CHECK(gw[0] == doctest::Approx(1.0));
  CHECK(run(1.3f, 2.0f) == 3);
  CHECK(gx[1] == doctest::Approx(0.4));
  CHECK(gw[0] == doctest::Approx(2.0));
}
