// Environment map: the uv convention on the axes, bilinear lookup at texel
// centres, across the seam and at the poles, derivatives with respect to
// texels and direction against central differences, forward against reverse.
#include "scene/scene_check.hpp"

using namespace dt_test;
using scene::EnvMap;

namespace {

constexpr int W = 8, H = 4;

// A random W x H map read through buffer 0 of an OverrideReader.
struct TestMap {
  std::vector<std::vector<double>> values{uniform_values(W * H * 3, 0.1, 2.0, 11)};
  EnvMap env = scene::equirect_environment(nullptr, W, H, 0);
  double texel(int row, int col, int ch) const { return values[0][std::size_t(scene::texel_index(W, row, col, ch))]; }
};

template <class S>
Vec3<S> dir3(double x, double y, double z) {
  return Vec3<S>(S(x), S(y), S(z));
}

// One colour channel as a function of one direction component.
template <class S>
S channel_along(const TestMap& m, Vec3<double> d, int comp, int ch, const S& x) {
  OverrideReader<S> r{&m.values};
  Vec3<S> ds(S(d.x), S(d.y), S(d.z));
  ds[comp] = x;
  return scene::lookup(r, m.env, ds)[ch];
}

}  // namespace

TEST_CASE_TEMPLATE("the six axis directions map to the documented uv", S, DT_ALL_SCALARS) {
  const double eps = tol<S>();
  const auto uv = [](double x, double y, double z) {
    const Vec2<S> r = scene::direction_to_uv(dir3<S>(x, y, z));
    return Vec2<double>(double(ad::value_of(r.x)), double(ad::value_of(r.y)));
  };
  CHECK(close(uv(0, 0, -1).x, 0.5, eps));  // -Z: the centre of the map
  CHECK(close(uv(0, 0, -1).y, 0.5, eps));
  CHECK(close(uv(1, 0, 0).x, 0.75, eps));  // +X: right of centre
  CHECK(close(uv(1, 0, 0).y, 0.5, eps));
  CHECK(close(uv(-1, 0, 0).x, 0.25, eps));
  CHECK(close(uv(-1, 0, 0).y, 0.5, eps));
  const double uz = uv(0, 0, 1).x;  // +Z: on the seam, u = 0 or 1
  CHECK((close(uz, 0.0, eps) || close(uz, 1.0, eps)));
  CHECK(close(uv(0, 0, 1).y, 0.5, eps));
  CHECK(close(uv(0, 1, 0).y, 0.0, eps));  // +Y: top row
  CHECK(close(uv(0, -1, 0).y, 1.0, eps));
  // the length of d does not matter
  CHECK(close(uv(3, 0, 0).x, 0.75, eps));
  CHECK(close(uv(0, 0, -0.01).y, 0.5, eps));
}

TEST_CASE("uv matches the docs/conventions.md formula on random directions and inverts") {
  std::mt19937 rng(3);
  std::normal_distribution<double> n01;
  for (int k = 0; k < 200; ++k) {
    Vec3d d(n01(rng), n01(rng), n01(rng));
    d = glm::normalize(d);
    const Vec2<double> uv = scene::direction_to_uv(d);
    CHECK(close(uv.x, 0.5 + std::atan2(d.x, -d.z) / (2 * pi_v<double>), 1e-12));
    CHECK(close(uv.y, std::acos(d.y) / pi_v<double>, 1e-12));
    const Vec3d back = scene::uv_to_direction(uv.x, uv.y);
    CHECK(glm::length(back - d) < 1e-12);
  }
}

TEST_CASE_TEMPLATE("bilinear lookup: texel centres, midpoints, seam, poles", S, float, double) {
  const TestMap m;
  OverrideReader<S> r{&m.values};
  const double eps = tol<S>();
  const auto at = [&](double u, double v, int ch) {
    return double(scene::lookup_uv(r, m.env, Vec2<S>(S(u), S(v)))[ch]);
  };
  for (int row = 0; row < H; ++row)
    for (int col = 0; col < W; ++col)
      for (int ch = 0; ch < 3; ++ch) {
        const double u = (col + 0.5) / W, v = (row + 0.5) / H;
        CHECK(close(at(u, v, ch), m.texel(row, col, ch), eps));
        if (row + 1 < H && col + 1 < W) {
          const double mean = 0.25 * (m.texel(row, col, ch) + m.texel(row, col + 1, ch) + m.texel(row + 1, col, ch) +
                                      m.texel(row + 1, col + 1, ch));
          CHECK(close(at(u + 0.5 / W, v + 0.5 / H, ch), mean, eps));
        }
      }
  // the seam: u = 0 and u = 1 are the same column boundary, halfway between
  // the last and the first column
  for (int ch = 0; ch < 3; ++ch) {
    const double v = 1.5 / H, expect = 0.5 * (m.texel(1, W - 1, ch) + m.texel(1, 0, ch));
    CHECK(close(at(0.0, v, ch), expect, eps));
    CHECK(close(at(1.0, v, ch), expect, eps));
    CHECK(close(at(0.25 / W, v, ch), 0.25 * m.texel(1, W - 1, ch) + 0.75 * m.texel(1, 0, ch), eps));
  }
  // u is periodic; any finite u is safe
  for (int ch = 0; ch < 3; ++ch) {
    const double u = 0.3125 + 0.1 / W, v = 0.6;
    CHECK(close(at(u + 3.0, v, ch), at(u, v, ch), eps * 10));
    CHECK(close(at(u - 2.0, v, ch), at(u, v, ch), eps * 10));
    CHECK(std::isfinite(at(1e20, v, ch)));
    CHECK(std::isfinite(at(-1e20, v, ch)));
  }
  // across the seam by direction (+Z, x slightly either side): nearly equal
  for (int ch = 0; ch < 3; ++ch) {
    const double left = double(scene::lookup(r, m.env, dir3<S>(-1e-4, 0.3, 1))[ch]);
    const double right = double(scene::lookup(r, m.env, dir3<S>(1e-4, 0.3, 1))[ch]);
    CHECK(std::abs(left - right) < 1e-3);
  }
  // the poles: within half a texel of v = 0 only the first row counts
  for (int ch = 0; ch < 3; ++ch) {
    const double u = 2.25 / W;
    const double row0 = 0.25 * m.texel(0, 1, ch) + 0.75 * m.texel(0, 2, ch);  // fu = 1.75
    CHECK(close(at(u, 0.0, ch), row0, eps));
    CHECK(close(at(u, 0.2 / H, ch), row0, eps));
    const double rowl = 0.25 * m.texel(H - 1, 1, ch) + 0.75 * m.texel(H - 1, 2, ch);
    CHECK(close(at(u, 1.0, ch), rowl, eps));
    CHECK(std::isfinite(double(scene::lookup(r, m.env, dir3<S>(0, 1, 0))[ch])));
    CHECK(std::isfinite(double(scene::lookup(r, m.env, dir3<S>(0, -1, 0))[ch])));
  }
}

TEST_CASE("constant environment and non-finite directions") {
  std::vector<std::vector<double>> values{{0.2, 0.5, 0.9}};
  EnvMap env = scene::constant_environment(nullptr, 0);
  OverrideReader<double> r{&values};
  const Vec3d c = scene::lookup(r, env, Vec3d(0.3, -0.2, 0.1));
  CHECK(c == Vec3d(0.2, 0.5, 0.9));
  for (int ch = 0; ch < 3; ++ch) {
    const double d = param_derivative<ad::Dual<double, 1>>(values, 0, ch, [&](auto& rd) {
      using R = decltype(rd.x);
      return scene::lookup(rd, env, Vec3<R>(R(1), R(2), R(3)))[ch];
    });
    CHECK(d == 1.0);
  }
  const TestMap m;
  OverrideReader<double> rm{&m.values};
  const Vec3d nan_dir(std::nan(""), 0.0, 1.0);
  const Vec3d cn = scene::lookup(rm, m.env, nan_dir);
  CHECK(cn == Vec3d(0.0));
}

TEST_CASE_TEMPLATE("derivative with respect to the texels matches central differences", S, DT_AD_SCALARS) {
  const TestMap m;
  const Vec3d dirs[] = {{0.3, 0.2, -1.0}, {0.0, 0.4, 1.0} /* the seam */, {1e-3, 1.0, 2e-3} /* near a pole */,
                        {0.0, -1.0, 0.0} /* the pole */, {-0.7, -0.1, 0.2}};
  for (const Vec3d& d : dirs) {
    for (std::int32_t i = 0; i < W * H * 3; ++i) {
      CAPTURE(d);
      CAPTURE(i);
      const int ch = i % 3;
      const auto f = [&](auto& rd) {
        using R = decltype(rd.x);
        return scene::lookup(rd, m.env, Vec3<R>(R(d.x), R(d.y), R(d.z)))[ch];
      };
      double value = 0;
      const double ad_d = param_derivative<S>(m.values, 0, i, f, &value);
      const double fd = param_difference(m.values, 0, i, f);
      CHECK(close(ad_d, fd, tol<S>() * 10));
      CHECK(ad_d >= 0.0);  // bilinear weights are non-negative
    }
  }
}

TEST_CASE_TEMPLATE("derivative with respect to the direction matches central differences", S, DT_AD_SCALARS) {
  const TestMap m;
  // generic directions, the seam (+Z half-plane, x = 0), near the poles
  const Vec3d dirs[] = {{0.3, 0.2, -1.0}, {-0.8, 0.5, 0.3}, {0.9, -0.6, -0.2}, {0.0, 0.4, 1.0},
                        {1e-4, -0.2, 1.0},  {2e-3, 1.0, -1e-3}, {-1e-3, -1.0, 3e-3}, {0.05, 0.97, 0.05}};
  for (const Vec3d& d : dirs) {
    for (int comp = 0; comp < 3; ++comp) {
      for (int ch = 0; ch < 3; ++ch) {
        CAPTURE(d);
        CAPTURE(comp);
        CAPTURE(ch);
        double value = 0;
        const double ad_d = derivative<S>([&](auto x) { return channel_along(m, d, comp, ch, x); }, d[comp], &value);
        const double fd = central_difference([&](double x) { return channel_along(m, d, comp, ch, x); }, d[comp], 1e-7);
        CHECK(close(value, channel_along(m, d, comp, ch, d[comp]), tol<S>()));
        // near the poles the derivative grows like 1 / r: compare relatively
        CHECK(std::abs(ad_d - fd) <= tol<S>() * 50 * std::max(1.0, std::abs(fd)));
      }
    }
  }
}

TEST_CASE_TEMPLATE("at and near the poles the direction derivative is finite", S, DT_AD_SCALARS) {
  const TestMap m;
  for (double y : {1.0, -1.0}) {
    for (double r : {0.0, 1e-20, 1e-30, 1e-40, 1e-7}) {
      for (int comp = 0; comp < 3; ++comp) {
        CAPTURE(y);
        CAPTURE(r);
        CAPTURE(comp);
        for (int ch = 0; ch < 3; ++ch) {
          double value = 0;
          const Vec3d d(r, y, -r);
          const double ad_d = derivative<S>([&](auto x) { return channel_along(m, d, comp, ch, x); }, d[comp], &value);
          CHECK(std::isfinite(value));
          CHECK(std::isfinite(ad_d));
        }
      }
    }
  }
  // exactly at the pole: the derivative along y is zero (v is flat there) and
  // the lookup is the first row's interpolation
  const Vec3d pole(0.0, 1.0, 0.0);
  for (int ch = 0; ch < 3; ++ch)
    CHECK(derivative<S>([&](auto x) { return channel_along(m, pole, 1, ch, x); }, 1.0) == 0.0);
}

TEST_CASE("forward and reverse mode agree through the library's readers") {
  const std::vector<double> texels = uniform_values(W * H * 3, 0.0, 3.0, 5);
  const std::vector<float> tf = to_float(texels);
  const EnvMap env = scene::equirect_environment(tf.data(), W, H, 2);
  const Vec3d dirs[] = {{0.3, 0.2, -1.0}, {0.0, 0.4, 1.0}, {1e-3, 1.0, 2e-3}, {-0.6, -0.9, 0.1}};
  for (const Vec3d& d : dirs) {
    for (int ch = 0; ch < 3; ++ch) {
      const auto g = check_forward_vs_reverse(tf, 2, [&](auto& reader) {
        using R = std::decay_t<decltype(reader.read(0, 0))>;
        // the direction is differentiable too: it rides on one texel's value
        const R w = reader.read(2, 0) * 0.01;
        return scene::lookup(reader, env, Vec3<R>(R(d.x) + w, R(d.y), R(d.z) - w))[ch];
      });
      // only the four bilinear taps (and texel 0, which moves the direction) have a gradient
      int nonzero = 0;
      for (std::size_t i = 1; i < g.size(); ++i) nonzero += g[i] != 0.0;
      CHECK(nonzero <= 4);
      CHECK(nonzero >= 1);
    }
  }
}

TEST_CASE("frozen texels cost no tape") {
  const std::vector<float> tf = to_float(uniform_values(W * H * 3, 0.0, 1.0, 9));
  ad::ParamSet set;
  ad::Tape<float> tape(1024);
  ad::LeafRecord log[16];
  ad::ParamReader<ad::Var<float>> rev(&set, &tape, log, 16);
  const EnvMap frozen = scene::equirect_environment(tf.data(), W, H);  // buffer -1
  const auto c = scene::lookup(rev, frozen, Vec3<ad::Var<float>>(0.1f, 0.2f, -1.0f));
  CHECK(rev.size() == 0);
  CHECK(tape.size() == 1);  // constant direction, constant texels: nothing recorded
  CHECK(c.x.is_constant());
}
