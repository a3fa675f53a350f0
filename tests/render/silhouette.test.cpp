// Silhouettes: the rasterizer against a brute-force double reference; the
// anti-aliased mask against exact and supersampled coverage; its gradients
// against a closed form, central differences, and forward vs reverse mode;
// occlusion, image border, degenerate and edge-on triangles; depth / normal
// maps and the smoothness term's gradient.
#include "support/ad_check.hpp"
#include "support/shapes.hpp"

#include <random>

#include "difftrans/losses/mask.hpp"
#include "difftrans/losses/screen_smoothness.hpp"
#include "difftrans/render/silhouette.hpp"

using namespace dt_test;
namespace dr = difftrans::render;
namespace ds = difftrans::scene;
namespace geometry = difftrans::geometry;
namespace losses = difftrans::losses;

namespace {

ds::TriangleMesh to_mesh(const Shape& s) { return ds::TriangleMesh(s.positions, s.triangles); }

// Camera on +Z at distance 3 looking at the origin, 40 degrees vertical fov.
ds::Camera front_camera(int w, int h) {
  return ds::look_at_camera(Vec3f(0, 0, 3), Vec3f(0), Vec3f(0, 1, 0), ds::protocol_camera_fov_y, w, h);
}

// A flat quad in the plane z = z0 with corners given in world x, y (counter-clockwise).
Shape quad(const float xy[4][2], float z0) {
  Shape s;
  for (int k = 0; k < 4; ++k) s.positions.insert(s.positions.end(), {xy[k][0], xy[k][1], z0});
  s.triangles = {0, 1, 2, 0, 2, 3};
  return s;
}

Shape append(Shape a, const Shape& b) {
  const std::int32_t base = std::int32_t(a.positions.size() / 3);
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  for (std::int32_t t : b.triangles) a.triangles.push_back(t + base);
  return a;
}

// Rotates a shape about the origin (x then y axis), to put edges at generic angles.
Shape rotated(Shape s, float ax, float ay) {
  for (std::size_t i = 0; i < s.positions.size(); i += 3) {
    float x = s.positions[i], y = s.positions[i + 1], z = s.positions[i + 2];
    const float y1 = std::cos(ax) * y - std::sin(ax) * z, z1 = std::sin(ax) * y + std::cos(ax) * z;
    const float x2 = std::cos(ay) * x + std::sin(ay) * z1, z2 = -std::sin(ay) * x + std::cos(ay) * z1;
    s.positions[i] = x2;
    s.positions[i + 1] = y1;
    s.positions[i + 2] = z2;
  }
  return s;
}

double sum(const std::vector<float>& v) {
  double s = 0.0;
  for (float x : v) s += x;
  return s;
}

// Errors of a mask against a reference coverage over the pixels the reference
// covers partially (0 < c < 1): mean and max absolute error, and the error of
// the totals relative to the reference total.
struct MaskError {
  double mean_edge = 0.0, max_edge = 0.0, total_rel = 0.0;
  int edge_pixels = 0;
};
MaskError compare(const std::vector<float>& mask, const std::vector<float>& ref) {
  MaskError e;
  double tm = 0.0, tr = 0.0;
  for (std::size_t p = 0; p < ref.size(); ++p) {
    tm += mask[p];
    tr += ref[p];
    if (ref[p] > 0.0f && ref[p] < 1.0f) {
      const double d = std::abs(double(mask[p]) - double(ref[p]));
      e.mean_edge += d;
      e.max_edge = std::max(e.max_edge, d);
      ++e.edge_pixels;
    }
  }
  if (e.edge_pixels) e.mean_edge /= e.edge_pixels;
  e.total_rel = std::abs(tm - tr) / std::max(tr, 1e-12);
  return e;
}

// A smooth weight image (so that Σ w·mask has no kinks where coverage moves
// between two neighbouring pixels of nearly equal weight).
std::vector<float> smooth_weights(int w, int h) {
  std::vector<float> a(std::size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) a[std::size_t(y) * w + x] = 1.0f + 0.5f * std::sin(0.11f * x + 0.3f) * std::cos(0.07f * y);
  return a;
}

template <class T>
double weighted(const std::vector<T>& mask, const std::vector<float>& w) {
  double s = 0.0;
  for (std::size_t p = 0; p < mask.size(); ++p) s += double(mask[p]) * w[p];
  return s;
}

// Positions moved by h along a direction (a float mesh with recomputed normals).
ds::TriangleMesh moved(const ds::TriangleMesh& m, const std::vector<float>& dir, double h) {
  std::vector<float> p = m.positions;
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = float(double(p[i]) + h * dir[i]);
  return ds::TriangleMesh(p, m.triangles);
}

std::vector<float> random_direction(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  std::vector<float> d(n);
  for (auto& x : d) x = g(rng);
  return d;
}

double dot(const std::vector<float>& a, const std::vector<float>& b) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) s += double(a[i]) * b[i];
  return s;
}

}  // namespace

// ------------------------------------------------------------------ topology

TEST_CASE("triangle neighbours: closed, open and non-manifold edges") {
  const auto box = geometry::TriangleNeighbors::build(to_mesh(make_box(0.5f, 0.5f, 0.5f)));
  for (std::size_t i = 0; i < box.across.size(); ++i) {
    REQUIRE(box.across[i] >= 0);
    // symmetric: the neighbour names this triangle back across the same edge
    const std::int32_t t = std::int32_t(i / 3), n = box.across[i];
    int back = 0;
    for (int k = 0; k < 3; ++k) back += box.across[std::size_t(3 * n + k)] == t;
    CHECK(back == 1);
  }
  const float sq[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  const auto open = geometry::TriangleNeighbors::build(to_mesh(quad(sq, 0.0f)));
  int boundary = 0;
  for (auto a : open.across) boundary += a == geometry::TriangleNeighbors::boundary;
  CHECK(boundary == 4);
  Shape fan;
  fan.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1};
  fan.triangles = {0, 1, 2, 1, 0, 3, 0, 1, 4};  // three faces on edge 0-1
  const auto nm = geometry::TriangleNeighbors::build(fan.triangles.data(), 3);
  CHECK(nm.across[0] == geometry::TriangleNeighbors::non_manifold);
  CHECK(nm.across[3] == geometry::TriangleNeighbors::non_manifold);
  CHECK(nm.across[6] == geometry::TriangleNeighbors::non_manifold);
  CHECK(nm.across[1] == geometry::TriangleNeighbors::boundary);
}

// ------------------------------------------------------------------ rasterizer

TEST_CASE("rasterize matches a brute-force double z-buffer") {
  // an icosphere and a few random triangles crossing it and the image border
  Shape s = rotated(make_icosphere(0.6f, 1), 0.4f, 0.7f);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int t = 0; t < 12; ++t) {
    Shape tri;
    for (int k = 0; k < 3; ++k) tri.positions.insert(tri.positions.end(), {1.3f * u(rng), 1.3f * u(rng), 0.8f * u(rng)});
    tri.triangles = {0, 1, 2};
    s = append(s, tri);
  }
  const ds::TriangleMesh m = to_mesh(s);
  const ds::Camera cam = ds::look_at_camera(Vec3f(0.3f, 0.2f, 3.0f), Vec3f(0), Vec3f(0, 1, 0), 0.6f, 48, 40);
  const dr::Raster r = dr::rasterize(m, cam);
  int compared = 0, skipped = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      // ray through the pixel centre in double; nearest triangle by Möller–Trumbore
      const Vec3d o(cam.position());
      const ds::Ray rf = cam.generate_ray(x, y);
      const Vec3d d(rf.direction);
      double best = 1e30, second = 1e30, margin = 1e30;
      int best_t = -1;
      for (int t = 0; t < m.num_triangles(); ++t) {
        Vec3d p[3];
        for (int k = 0; k < 3; ++k) p[k] = Vec3d(m.positions[3 * m.triangles[3 * t + k]], m.positions[3 * m.triangles[3 * t + k] + 1],
                                                  m.positions[3 * m.triangles[3 * t + k] + 2]);
        const auto h = ds::intersect_triangle(o, d, p[0], p[1], p[2]);
        if (!h.valid) continue;
        const double b0 = 1 - h.b1 - h.b2, edge = std::min(b0, std::min(h.b1, h.b2));
        if (h.t > 0 && edge > -1e-4) margin = std::min(margin, std::abs(edge));  // the centre is on or near an edge
        if (edge < 0 || h.t <= 0) continue;
        const double depth = h.t * glm::dot(d, Vec3d(-cam.camera_to_world[2]));
        if (depth < best) {
          second = best;
          best = depth;
          best_t = t;
        } else {
          second = std::min(second, depth);
        }
      }
      const std::size_t p = std::size_t(y) * cam.width + x;
      if (margin < 1e-4 || (best_t >= 0 && second - best < 1e-4)) {
        ++skipped;
        continue;
      }
      ++compared;
      REQUIRE(r.triangle[p] == best_t);
      if (best_t < 0) {
        CHECK(std::isinf(r.depth[p]));
        continue;
      }
      CHECK(r.depth[p] == doctest::Approx(best).epsilon(1e-5));
      // the barycentrics give the point on the pixel ray at that depth
      const std::int32_t* tri = m.triangles.data() + 3 * best_t;
      Vec3d q(0.0);
      const double bb[3] = {1.0 - r.b1[p] - r.b2[p], r.b1[p], r.b2[p]};
      for (int k = 0; k < 3; ++k)
        q += bb[k] * Vec3d(m.positions[3 * tri[k]], m.positions[3 * tri[k] + 1], m.positions[3 * tri[k] + 2]);
      const Vec3d along = o + d * (best / glm::dot(d, Vec3d(-cam.camera_to_world[2])));
      CHECK(glm::length(q - along) < 1e-4);
    }
  CHECK(compared > 1880);
  CHECK(skipped < 40);
}

TEST_CASE("rasterize: near-plane rejection, degenerate triangles, both windings") {
  const ds::Camera cam = front_camera(16, 16);
  Shape s;
  s.positions = {-0.5f, -0.5f, 0.0f, 0.5f, -0.5f, 0.0f, 0.0f, 0.5f, 0.0f,     // CCW seen from the camera
                 -0.5f, -0.5f, 0.0f, 0.0f, 0.5f, 0.0f, 0.5f, -0.5f, 0.0f,     // the same, clockwise
                 -0.3f, 0.0f, 3.5f, 0.3f, 0.0f, 1.0f, 0.0f, 0.4f, 1.0f,       // one vertex behind the camera
                 -0.2f, -0.2f, 0.5f, 0.0f, 0.0f, 0.5f, 0.2f, 0.2f, 0.5f};     // collinear: zero area
  s.triangles = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
  const ds::TriangleMesh m = to_mesh(s);
  const dr::Raster r = dr::rasterize(m, cam);
  int covered = 0;
  for (std::int32_t t : r.triangle) {
    CHECK((t == -1 || t == 0 || t == 1));  // 0 and 1 coincide (either may round nearer); 2 and 3 are not drawn
    covered += t >= 0;
  }
  CHECK(covered > 10);
  Shape cw;
  cw.positions = std::vector<float>(s.positions.begin() + 9, s.positions.begin() + 18);
  cw.triangles = {0, 1, 2};
  const dr::Raster rc = dr::rasterize(to_mesh(cw), cam);
  for (std::size_t p = 0; p < r.triangle.size(); ++p) CHECK((rc.triangle[p] >= 0) == (r.triangle[p] >= 0));
}

// ------------------------------------------------------------------ the per-pair computation

TEST_CASE("pair_coverage: values of a vertical and a slanted edge") {
  // horizontal pair (10, 5)-(11, 5): centres at x = 10.5 and 11.5, boundary at 11
  const Vec2<double> a(11.3, 0.0), b(11.3, 20.0);
  auto pc = dr::pair_coverage(a, b, 10, 5, 0, true);
  CHECK(pc.gain == doctest::Approx(0.3));
  CHECK(pc.loss == 0.0);
  pc = dr::pair_coverage(a, b, 10, 5, 0, false);  // the right pixel is covered, the surface reaches left to 11.3
  CHECK(pc.gain == 0.0);
  CHECK(pc.loss == doctest::Approx(0.3));
  // slanted: crosses y = 5.5 at x = 10.8 (loses 0.2 from the low covered pixel)
  const Vec2<double> c(10.0, 3.5), e(11.6, 7.5);
  pc = dr::pair_coverage(c, e, 10, 5, 0, true);
  CHECK(pc.loss == doctest::Approx(0.2));
  // vertical pair (4, 7)-(4, 8): line x = 4.5, boundary y = 8
  const Vec2<double> f(0.0, 8.4), g(9.0, 8.1);
  pc = dr::pair_coverage(f, g, 4, 7, 1, true);
  CHECK(pc.gain == doctest::Approx(8.4 - 0.3 * 4.5 / 9.0 - 8.0));
}

TEST_CASE_TEMPLATE("pair_coverage: derivatives match central differences", S, ad::Dual<double, 1>, ad::Var<double>) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.45, 0.45), far(-6.0, 6.0);
  int checked = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const int axis = trial % 2;
    const bool low = (trial / 2) % 2 == 0;
    // an edge through (boundary + u, line) with a random steep direction
    const double cu = 11.0 + u(rng), cv = 5.5;
    const double du = far(rng) * 0.3, dv = (trial % 3 == 0 ? -1.0 : 1.0) * (2.0 + std::abs(far(rng)));
    double coords[4] = {cu - 0.4 * du, cv - 0.4 * dv, cu + 0.6 * du, cv + 0.6 * dv};
    if (axis == 1) {
      std::swap(coords[0], coords[1]);
      std::swap(coords[2], coords[3]);
    }
    const int x = axis == 0 ? 10 : 5, y = axis == 0 ? 5 : 10;
    for (int i = 0; i < 4; ++i) {
      const auto f = [&](auto v) {
        using R = decltype(v);
        R c[4] = {R(coords[0]), R(coords[1]), R(coords[2]), R(coords[3])};
        c[i] = v;
        const auto pc = dr::pair_coverage(Vec2<R>(c[0], c[1]), Vec2<R>(c[2], c[3]), x, y, axis, low);
        return R(2.0) * pc.gain - R(3.0) * pc.loss;  // distinct weights: both outputs are seen
      };
      const double ad = derivative<S>(f, coords[i]);
      const double fd = central_difference(f, coords[i]);
      CHECK(ad == doctest::Approx(fd).epsilon(1e-6));
      ++checked;
    }
  }
  CHECK(checked == 160);
}

// ------------------------------------------------------------------ coverage

TEST_CASE("AA mask of an axis-aligned rectangle is exact except at its four corners") {
  const ds::Camera cam = front_camera(64, 64);
  // world half-size a projects to [32 - f a / 3, 32 + f a / 3]; pick fractional edges
  const float a = 0.41f, b = 0.27f;
  const float sq[4][2] = {{-a, -b}, {a + 0.05f, -b}, {a + 0.05f, b + 0.08f}, {-a, b + 0.08f}};
  // split: the same rectangle with a strip 0.25 pixel wide along its right side
  // (two thin triangles that cover no pixel centre, sharing the split line):
  // the walk must cross it to reach the silhouette edge
  const float xs = a + 0.05f - 0.25f * 3.0f / cam.fx;
  Shape split;
  split.positions = {-a, -b, 0, xs, -b, 0, xs, b + 0.08f, 0, -a, b + 0.08f, 0, a + 0.05f, -b, 0, a + 0.05f, b + 0.08f, 0};
  split.triangles = {0, 1, 2, 0, 2, 3, 1, 4, 5, 1, 5, 2};
  for (bool with_strip : {false, true}) {
  CAPTURE(with_strip);
  const ds::TriangleMesh m = to_mesh(with_strip ? split : quad(sq, 0.0f));
  const std::vector<float> mask = dr::silhouette_mask(m, cam);
  // exact coverage: product of interval overlaps in pixel coordinates
  const auto px = [&](float wx) { return double(cam.cx) + double(cam.fx) * wx / 3.0; };
  const auto py = [&](float wy) { return double(cam.cy) - double(cam.fy) * wy / 3.0; };
  const double x0 = px(-a), x1 = px(a + 0.05f), y0 = py(b + 0.08f), y1 = py(-b);
  const auto overlap = [](double lo, double hi, int i) { return std::max(0.0, std::min(hi, i + 1.0) - std::max(lo, double(i))); };
  int corners = 0, edge_pixels = 0;
  double binary_err = 0.0, aa_err = 0.0;
  const std::vector<float> binary = dr::coverage_mask(dr::rasterize(m, cam));
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      const double ox = overlap(x0, x1, x), oy = overlap(y0, y1, y), exact = ox * oy;
      const std::size_t p = std::size_t(y) * 64 + x;
      const bool corner = ox > 0 && ox < 1 && oy > 0 && oy < 1;
      if (corner) {
        ++corners;
        // the two 1-D estimates, one per direction: a covered centre loses both
        // shortfalls, an uncovered one gains from the neighbour whose centre is covered
        const double expected = ox > 0.5 && oy > 0.5 ? ox + oy - 1.0 : ox > 0.5 ? oy : oy > 0.5 ? ox : 0.0;
        CHECK(mask[p] == doctest::Approx(expected).epsilon(1e-4));
        CHECK(std::abs(mask[p] - exact) <= 0.25 + 1e-5);
      } else {
        CHECK(mask[p] == doctest::Approx(exact).epsilon(1e-4));
      }
      if (exact > 0 && exact < 1) {
        ++edge_pixels;
        binary_err += std::abs(binary[p] - exact);
        aa_err += std::abs(mask[p] - exact);
      }
    }
  CHECK(corners == 4);
  CHECK(edge_pixels > 60);
  CHECK(aa_err < 0.05 * binary_err);
  }
}

TEST_CASE("AA mask approaches the 16x16 supersampled coverage (triangle, rotated square, icosphere)") {
  const ds::Camera cam = front_camera(96, 80);
  struct Case {
    std::string name;
    Shape shape;
    double mean_edge, total_rel;  // bounds on the AA error
  };
  Shape tri;
  tri.positions = {-0.61f, -0.47f, 0.0f, 0.52f, -0.33f, 0.1f, -0.08f, 0.58f, -0.2f};
  tri.triangles = {0, 1, 2};
  const float sq[4][2] = {{-0.5f, -0.5f}, {0.5f, -0.5f}, {0.5f, 0.5f}, {-0.5f, 0.5f}};
  std::vector<Case> cases = {{"triangle", tri, 0.03, 1e-3},
                             {"rotated square", rotated(quad(sq, 0.0f), 0.3f, 0.5f), 0.03, 1e-3},
                             {"icosphere", rotated(make_icosphere(0.7f, 3), 0.2f, 0.3f), 0.03, 1e-3}};
  // in-plane rotation of the square by 0.35 rad, so no edge is axis-aligned
  for (std::size_t i = 0; i < cases[1].shape.positions.size(); i += 3) {
    float& x = cases[1].shape.positions[i];
    float& y = cases[1].shape.positions[i + 1];
    const float c = std::cos(0.35f), s = std::sin(0.35f), x0 = x, y0 = y;
    x = c * x0 - s * y0;
    y = s * x0 + c * y0;
  }
  for (const Case& c : cases) {
    CAPTURE(c.name);
    const ds::TriangleMesh m = to_mesh(c.shape);
    const std::vector<float> ref = dr::supersampled_coverage(m, cam, 16);
    const std::vector<float> aa = dr::silhouette_mask(m, cam);
    const std::vector<float> bin = dr::coverage_mask(dr::rasterize(m, cam));
    const MaskError ea = compare(aa, ref), eb = compare(bin, ref);
    MESSAGE(c.name << ": edge pixels " << ea.edge_pixels << ", mean |AA - ref| " << ea.mean_edge << " (binary "
                   << eb.mean_edge << "), max " << ea.max_edge << " (binary " << eb.max_edge << "), total rel "
                   << ea.total_rel << " (binary " << eb.total_rel << ")");
    CHECK(ea.edge_pixels > 100);
    CHECK(ea.mean_edge < c.mean_edge);
    CHECK(ea.mean_edge < 0.25 * eb.mean_edge);
    CHECK(ea.total_rel < c.total_rel);
    CHECK(ea.max_edge < 0.35);
  }
}

// ------------------------------------------------------------------ gradients

TEST_CASE("gradient of the total coverage of a triangle approaches its projected area's") {
  Shape tri;
  tri.positions = {-0.61f, -0.47f, 0.0f, 0.52f, -0.33f, 0.1f, -0.08f, 0.58f, -0.2f};
  tri.triangles = {0, 1, 2};
  const ds::TriangleMesh m = to_mesh(tri);
  double err[2] = {0.0, 0.0};
  int res = 0;
  for (int size : {128, 512}) {
    const ds::Camera cam = front_camera(size, size);
    const std::vector<float> ones(std::size_t(size) * size, 1.0f);
    std::vector<float> grad(9, 0.0f);
    const std::vector<float> mask = dr::silhouette_gradient(m, cam, ones.data(), grad.data());
    // closed form: area of the projected triangle, differentiated by Dual in double
    using D = ad::Dual<double, 1>;
    double area = 0.0, worst = 0.0, scale = 0.0;
    for (int i = 0; i < 9; ++i) {
      Vec3<D> p[3];
      for (int k = 0; k < 3; ++k) p[k] = Vec3<D>(D(m.positions[3 * k]), D(m.positions[3 * k + 1]), D(m.positions[3 * k + 2]));
      p[i / 3][i % 3].grad[0] = 1.0;
      Vec2<D> q[3];
      for (int k = 0; k < 3; ++k) q[k] = cam.project(p[k]).pixel;
      const Vec2<D> e1 = q[1] - q[0], e2 = q[2] - q[0];
      const D a = D(0.5) * abs(e1.x * e2.y - e1.y * e2.x);
      area = a.value;
      worst = std::max(worst, std::abs(grad[std::size_t(i)] - a.grad[0]));
      scale = std::max(scale, std::abs(a.grad[0]));
    }
    err[res++] = worst / scale;
    MESSAGE(size << "^2: total coverage " << sum(mask) << " vs area " << area << ", max gradient error "
                 << worst / scale << " of the largest component");
    CHECK(sum(mask) == doctest::Approx(area).epsilon(2e-3));
  }
  CHECK(err[0] < 0.03);
  CHECK(err[1] < 0.4 * err[0]);  // the corners' share shrinks with the resolution
}

TEST_CASE("silhouette_gradient matches central differences of the AA mask (double)") {
  const ds::Camera cam = front_camera(64, 56);
  const ds::TriangleMesh m = to_mesh(rotated(make_icosphere(0.6f, 2), 0.5f, 0.2f));
  const geometry::TriangleNeighbors nb = geometry::TriangleNeighbors::build(m);
  const std::vector<float> w = smooth_weights(cam.width, cam.height);
  std::vector<float> grad(m.positions.size(), 0.0f);
  dr::SilhouetteStats st;
  dr::silhouette_gradient(m, cam, w.data(), grad.data(), &nb, {}, &st);
  CHECK(st.crossings > 60);
  const double h = 5e-5;  // world units: about 0.002 pixel
  const auto loss = [&](const std::vector<float>& dir, double step) {
    return weighted(dr::silhouette_mask<double>(moved(m, dir, step), cam, &nb), w);
  };
  // The 1-D AA mask is continuous but has kinks (where coverage moves between
  // two pixels) and small jumps near silhouette vertices when a pixel centre
  // changes sides: compare where the raster's coverage stays the same.
  const dr::Raster base = dr::rasterize(m, cam);
  const auto same_coverage = [&](const std::vector<float>& dir) {
    for (double step : {-h, h}) {
      const dr::Raster r = dr::rasterize(moved(m, dir, step), cam);
      for (std::size_t p = 0; p < r.triangle.size(); ++p)
        if ((r.triangle[p] >= 0) != (base.triangle[p] >= 0)) return false;
    }
    return true;
  };
  // single coordinates: the twelve with the largest gradient
  std::vector<int> order(grad.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = int(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return std::abs(grad[a]) > std::abs(grad[b]); });
  int checked = 0;
  for (int k = 0; k < 12; ++k) {
    std::vector<float> dir(grad.size(), 0.0f);
    dir[std::size_t(order[k])] = 1.0f;
    if (!same_coverage(dir)) continue;
    const double fd = (loss(dir, h) - loss(dir, -h)) / (2 * h);
    CAPTURE(order[k]);
    CHECK(grad[std::size_t(order[k])] == doctest::Approx(fd).epsilon(0.002));
    ++checked;
  }
  CHECK(checked >= 8);
  // random directions: the error relative to sum |g_i dir_i| (the scale of the cancellation)
  checked = 0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    const std::vector<float> dir = random_direction(m.positions.size(), seed);
    if (!same_coverage(dir)) continue;
    const double fd = (loss(dir, h) - loss(dir, -h)) / (2 * h), ad = dot(grad, dir);
    double scale = 0.0;
    for (std::size_t i = 0; i < dir.size(); ++i) scale += std::abs(double(grad[i]) * dir[i]);
    CAPTURE(seed);
    CHECK(std::abs(ad - fd) < 1e-3 * scale);
    ++checked;
  }
  CHECK(checked >= 2);
}

TEST_CASE("forward mode (Dual) agrees with reverse mode (Var) on the mask") {
  const ds::Camera cam = front_camera(80, 64);
  const ds::TriangleMesh m = to_mesh(rotated(make_icosphere(0.7f, 3), 0.1f, 0.9f));
  const std::vector<float> w = smooth_weights(cam.width, cam.height);
  std::vector<float> grad(m.positions.size(), 0.0f);
  const std::vector<float> mask = dr::silhouette_gradient(m, cam, w.data(), grad.data());
  const std::vector<float> dir = random_direction(m.positions.size(), 9);
  const dr::MaskDerivative md = dr::silhouette_derivative(m, cam, dir.data());
  for (std::size_t p = 0; p < mask.size(); ++p) REQUIRE(md.value[p] == doctest::Approx(mask[p]).epsilon(1e-6));
  double fwd = 0.0;
  int moving = 0;
  for (std::size_t p = 0; p < mask.size(); ++p) {
    fwd += double(md.derivative[p]) * w[p];
    moving += md.derivative[p] != 0.0f;
  }
  CHECK(moving > 100);
  CHECK(dot(grad, dir) == doctest::Approx(fwd).epsilon(1e-4));
}

TEST_CASE("AA derivative follows the supersampled coverage under a growing sphere") {
  const ds::Camera cam = front_camera(64, 64);
  const ds::TriangleMesh m = to_mesh(rotated(make_icosphere(0.6f, 3), 0.3f, 0.4f));
  const std::vector<float> radial = m.positions;  // d p / d scale
  const dr::MaskDerivative md = dr::silhouette_derivative(m, cam, radial.data());
  const double h = 0.005;  // about 0.13 pixel at the silhouette; 64x64 samples resolve it
  const std::vector<float> cp = dr::supersampled_coverage(moved(m, radial, h), cam, 64);
  const std::vector<float> cm = dr::supersampled_coverage(moved(m, radial, -h), cam, 64);
  double fd_total = 0.0, ad_total = 0.0, diff = 0.0, norm = 0.0;
  for (std::size_t p = 0; p < cp.size(); ++p) {
    const double fd = (double(cp[p]) - cm[p]) / (2 * h);
    fd_total += fd;
    ad_total += md.derivative[p];
    diff += std::abs(fd - md.derivative[p]);
    norm += std::abs(fd);
  }
  MESSAGE("d coverage / d scale: AA " << ad_total << ", supersampled FD " << fd_total << "; per-pixel relative L1 "
                                      << diff / norm);
  CHECK(ad_total == doctest::Approx(fd_total).epsilon(0.02));
  CHECK(diff / norm < 0.3);
}

// ------------------------------------------------------------------ special cases

TEST_CASE("occlusion: hidden geometry gets no mask change and no gradient") {
  const ds::Camera cam = front_camera(64, 64);
  const float big[4][2] = {{-0.6f, -0.55f}, {0.62f, -0.55f}, {0.62f, 0.6f}, {-0.6f, 0.6f}};
  const float small[4][2] = {{-0.2f, -0.2f}, {0.25f, -0.15f}, {0.2f, 0.3f}, {-0.25f, 0.2f}};
  const Shape back = quad(big, 0.0f);
  for (float z : {0.5f, -0.5f}) {  // the small quad in front of, then behind the big one
    CAPTURE(z);
    const ds::TriangleMesh both = to_mesh(append(back, quad(small, z)));
    const ds::TriangleMesh alone = to_mesh(back);
    const std::vector<float> w = smooth_weights(64, 64);
    std::vector<float> g_both(both.positions.size(), 0.0f), g_alone(alone.positions.size(), 0.0f);
    const std::vector<float> mb = dr::silhouette_gradient(both, cam, w.data(), g_both.data());
    const std::vector<float> ma = dr::silhouette_gradient(alone, cam, w.data(), g_alone.data());
    for (std::size_t p = 0; p < ma.size(); ++p) REQUIRE(mb[p] == ma[p]);
    for (std::size_t i = 0; i < g_alone.size(); ++i) CHECK(g_both[i] == g_alone[i]);
    for (std::size_t i = g_alone.size(); i < g_both.size(); ++i) CHECK(g_both[i] == 0.0f);
  }
  // a front triangle sticking out of the big quad: the union's coverage, and
  // gradient only for its own vertices whose edges form the silhouette
  Shape stick;
  stick.positions = {0.3f, 0.0f, 0.4f, 1.1f, 0.2f, 0.4f, 0.4f, 0.35f, 0.4f};
  stick.triangles = {0, 1, 2};
  const ds::TriangleMesh u = to_mesh(append(back, stick));
  const MaskError e = compare(dr::silhouette_mask(u, cam), dr::supersampled_coverage(u, cam, 16));
  CHECK(e.mean_edge < 0.06);
  CHECK(e.total_rel < 2e-3);
}

TEST_CASE("triangles crossing the image border") {
  const ds::Camera cam = front_camera(48, 40);
  Shape s;
  s.positions = {-2.0f, -0.3f, 0.0f, 0.35f, -0.45f, 0.05f, 0.1f, 1.9f, -0.1f};
  s.triangles = {0, 1, 2};
  const ds::TriangleMesh m = to_mesh(s);
  const dr::SilhouetteFrame f = dr::prepare_silhouette(m, geometry::TriangleNeighbors::build(m), cam);
  for (const auto& c : f.crossings) {
    REQUIRE(c.covered >= 0);
    REQUIRE(c.covered < cam.width * cam.height);
    REQUIRE(c.other >= 0);
    REQUIRE(c.other < cam.width * cam.height);
  }
  const MaskError e = compare(dr::silhouette_mask(m, cam), dr::supersampled_coverage(m, cam, 16));
  CHECK(e.mean_edge < 0.06);
  CHECK(e.total_rel < 2e-3);
  // vertex 0 lies outside the image, yet its edges cross it: it has a gradient, and it matches FD
  const std::vector<float> w = smooth_weights(cam.width, cam.height);
  std::vector<float> grad(9, 0.0f);
  dr::silhouette_gradient(m, cam, w.data(), grad.data());
  for (float g : grad) CHECK(std::isfinite(g));
  CHECK(std::abs(grad[0]) + std::abs(grad[1]) > 0.0f);
  for (int i : {0, 1, 4}) {
    std::vector<float> dir(9, 0.0f);
    dir[std::size_t(i)] = 1.0f;
    const double h = 2e-4;
    const double fd = (weighted(dr::silhouette_mask<double>(moved(m, dir, h), cam), w) -
                       weighted(dr::silhouette_mask<double>(moved(m, dir, -h), cam), w)) / (2 * h);
    CAPTURE(i);
    CHECK(grad[std::size_t(i)] == doctest::Approx(fd).epsilon(0.01));
  }
}

TEST_CASE("degenerate triangles change nothing and give finite gradients") {
  const ds::Camera cam = front_camera(48, 48);
  const Shape sphere = rotated(make_icosphere(0.6f, 2), 0.2f, 0.1f);
  Shape deg = sphere;
  const std::int32_t nv = std::int32_t(sphere.positions.size() / 3);
  // a repeated vertex, a collinear triple on the silhouette's side, and a point triangle
  deg.positions.insert(deg.positions.end(), {0.75f, 0.0f, 0.0f, 0.9f, 0.1f, 0.0f, 1.05f, 0.2f, 0.0f});
  deg.triangles.insert(deg.triangles.end(), {0, 0, 1, nv, nv + 1, nv + 2, 5, 5, 5});
  const ds::TriangleMesh ms = to_mesh(sphere), md = to_mesh(deg);
  const std::vector<float> w = smooth_weights(48, 48);
  std::vector<float> gs(ms.positions.size(), 0.0f), gd(md.positions.size(), 0.0f);
  const std::vector<float> a = dr::silhouette_gradient(ms, cam, w.data(), gs.data());
  const std::vector<float> b = dr::silhouette_gradient(md, cam, w.data(), gd.data());
  for (std::size_t p = 0; p < a.size(); ++p) REQUIRE(a[p] == b[p]);
  for (std::size_t i = 0; i < gs.size(); ++i) CHECK(gd[i] == doctest::Approx(gs[i]).epsilon(1e-5));
  for (std::size_t i = gs.size(); i < gd.size(); ++i) CHECK(gd[i] == 0.0f);
  const dr::MaskDerivative fwd = dr::silhouette_derivative(md, cam, random_direction(md.positions.size(), 4).data());
  for (float d : fwd.derivative) CHECK(std::isfinite(d));
}

TEST_CASE("a mesh seen edge-on") {
  const ds::Camera cam = front_camera(40, 40);
  // a quad in the plane x = 0: contains the viewing direction, covers nothing
  Shape s;
  s.positions = {0.0f, -0.5f, -0.5f, 0.0f, -0.5f, 0.5f, 0.0f, 0.5f, 0.5f, 0.0f, 0.5f, -0.5f};
  s.triangles = {0, 1, 2, 0, 2, 3};
  const ds::TriangleMesh m = to_mesh(s);
  const std::vector<float> w = smooth_weights(40, 40);
  std::vector<float> grad(m.positions.size(), 0.0f);
  const std::vector<float> mask = dr::silhouette_gradient(m, cam, w.data(), grad.data());
  CHECK(sum(mask) == 0.0);
  for (float g : grad) CHECK(g == 0.0f);
  // a box with two faces edge-on (seen straight along z): still the supersampled coverage
  const ds::TriangleMesh box = to_mesh(make_box(0.4f, 0.3f, 0.35f));
  const MaskError e = compare(dr::silhouette_mask(box, cam), dr::supersampled_coverage(box, cam, 16));
  CHECK(e.total_rel < 0.01);
  CHECK(e.mean_edge < 0.06);
}

TEST_CASE("mask_l1: value and subgradient") {
  const std::vector<float> mask = {0.2f, 1.0f, 0.5f, 0.0f};
  const float target[4] = {0.0f, 1.0f, 1.0f, 0.25f};
  float adj[4];
  const double l = losses::mask_l1(mask, target, adj);
  CHECK(l == doctest::Approx((0.2 + 0.0 + 0.5 + 0.25) / 4.0));
  CHECK(adj[0] == 0.25f);
  CHECK(adj[1] == 0.0f);
  CHECK(adj[2] == -0.25f);
  CHECK(adj[3] == -0.25f);
}

TEST_CASE("mask L1 gradient step moves the silhouette toward the target") {
  const ds::Camera cam = front_camera(64, 64);
  const ds::TriangleMesh target = to_mesh(make_icosphere(0.6f, 3));
  const ds::TriangleMesh start = to_mesh(make_icosphere(0.5f, 3));
  const std::vector<float> tmask = dr::silhouette_mask(target, cam);
  std::vector<float> adj(tmask.size());
  const double l0 = losses::mask_l1(dr::silhouette_mask(start, cam), tmask.data(), adj.data());
  std::vector<float> grad(start.positions.size(), 0.0f);
  dr::silhouette_gradient(start, cam, adj.data(), grad.data());
  // the gradient points inward (growing lowers the loss): it is anti-parallel to the positions
  CHECK(dot(grad, start.positions) < 0.0);
  double gn = 0.0;
  for (float g : grad) gn += double(g) * g;
  std::vector<float> step(grad.size());
  for (std::size_t i = 0; i < grad.size(); ++i) step[i] = float(-grad[i] / std::sqrt(gn));
  const double l1 = losses::mask_l1(dr::silhouette_mask(moved(start, step, 0.05), cam), tmask.data());
  CHECK(l1 < l0);
}

// ------------------------------------------------------------------ depth, normals, smoothness

TEST_CASE("depth and normal maps of planes and a sphere") {
  const ds::Camera cam = front_camera(32, 32);
  const float sq[4][2] = {{-0.6f, -0.6f}, {0.6f, -0.6f}, {0.6f, 0.6f}, {-0.6f, 0.6f}};
  {
    const ds::TriangleMesh m = to_mesh(quad(sq, 0.25f));
    const losses::GeometryMaps g = losses::geometry_maps(m, cam, dr::rasterize(m, cam));
    int valid = 0;
    for (std::size_t p = 0; p < g.valid.size(); ++p) {
      if (!g.valid[p]) continue;
      ++valid;
      CHECK(g.depth[p] == doctest::Approx(2.75f).epsilon(1e-5));
      CHECK(g.normal[3 * p + 2] == doctest::Approx(1.0f));
    }
    CHECK(valid > 100);
    CHECK(losses::smoothness_loss(g) == doctest::Approx(0.0).epsilon(1e-6));
  }
  {
    // tilted plane z = 0.3 x: depth along the pixel ray, closed form
    Shape s = quad(sq, 0.0f);
    for (std::size_t i = 0; i < s.positions.size(); i += 3) s.positions[i + 2] = 0.3f * s.positions[i];
    const ds::TriangleMesh m = to_mesh(s);
    const dr::Raster r = dr::rasterize(m, cam);
    const losses::GeometryMaps g = losses::geometry_maps(m, cam, r);
    for (std::size_t p = 0; p < g.valid.size(); ++p) {
      if (!g.valid[p]) continue;
      const double dx = (double(p % 32) + 0.5 - cam.cx) / cam.fx;  // camera ray (dx, dy, -1), eye at z = 3
      const double depth = 3.0 / (1.0 + 0.3 * dx);                  // 3 - t = 0.3 * dx * t
      CHECK(g.depth[p] == doctest::Approx(depth).epsilon(1e-5));
      CHECK(r.depth[p] == doctest::Approx(depth).epsilon(1e-5));
    }
  }
  {
    const ds::TriangleMesh m = to_mesh(make_icosphere(0.7f, 3));
    const dr::Raster r = dr::rasterize(m, cam);
    const losses::GeometryMaps g = losses::geometry_maps(m, cam, r);
    double worst = 0.0;
    for (std::size_t p = 0; p < g.valid.size(); ++p) {
      if (!g.valid[p]) continue;
      const ds::Ray ray = cam.generate_ray(int(p % 32), int(p / 32));
      const Vec3f x = ray.origin + ray.direction * (g.depth[p] / -glm::dot(ray.direction, Vec3f(0, 0, 1)) * 1.0f);
      const Vec3f n(g.normal[3 * p], g.normal[3 * p + 1], g.normal[3 * p + 2]);
      worst = std::max(worst, double(glm::length(n - glm::normalize(x))));
    }
    CHECK(worst < 0.03);
    CHECK(losses::smoothness_loss(g) > 0.0);
  }
}

TEST_CASE("geometry_backward matches central differences of the maps (raster held fixed)") {
  const ds::Camera cam = front_camera(40, 40);
  const ds::TriangleMesh m = to_mesh(rotated(make_icosphere(0.6f, 2), 0.3f, 0.6f));
  const dr::Raster r = dr::rasterize(m, cam);
  // a linear functional of the maps: random weights on depth and normal
  std::vector<float> wd = random_direction(r.triangle.size(), 21), wn = random_direction(3 * r.triangle.size(), 22);
  // evaluated in double by the same generic per-pixel code, positions as constants
  const auto functional = [&](const ds::TriangleMesh& mm, bool face) {
    ad::ParamReader<double> reader(nullptr);
    double s = 0.0;
    for (std::size_t p = 0; p < r.triangle.size(); ++p) {
      if (r.triangle[p] < 0) continue;
      const auto g = losses::pixel_geometry<double>(reader, mm.view(), cam, r.triangle[p], int(p % 40), int(p / 40), face,
                                                ds::NormalMode::one_ring);
      if (!g.valid) continue;
      s += double(wd[p]) * g.depth;
      for (int c = 0; c < 3; ++c) s += double(wn[3 * p + c]) * g.n[c];
    }
    return s;
  };
  for (bool face : {false, true}) {
    CAPTURE(face);
    losses::SmoothnessOptions opt;
    opt.face_normals = face;
    std::vector<float> grad(m.positions.size(), 0.0f);
    losses::geometry_backward(m, cam, r, wd.data(), wn.data(), grad.data(), opt);
    for (unsigned seed : {31u, 32u, 33u}) {
      const std::vector<float> dir = random_direction(m.positions.size(), seed);
      const double h = 1e-4;
      const double fd = (functional(moved(m, dir, h), face) - functional(moved(m, dir, -h), face)) / (2 * h);
      CAPTURE(seed);
      CHECK(dot(grad, dir) == doctest::Approx(fd).epsilon(3e-3));
    }
  }
}

TEST_CASE("smoothness_loss adjoints match central differences in the map values") {
  const ds::Camera cam = front_camera(24, 24);
  const ds::TriangleMesh m = to_mesh(rotated(make_icosphere(0.7f, 2), 0.3f, 0.6f));
  losses::GeometryMaps g = losses::geometry_maps(m, cam, dr::rasterize(m, cam));
  losses::SmoothnessOptions opt;
  opt.depth_weight = 0.7f;
  opt.laplacian_weight = 1.3f;
  std::vector<float> ad_d(g.depth.size()), ad_n(g.normal.size());
  const double l0 = losses::smoothness_loss(g, opt, ad_d.data(), ad_n.data());
  CHECK(l0 > 0.0);
  int checked = 0;
  for (std::size_t p = 0; p < g.valid.size(); p += 7) {
    if (!g.valid[p]) continue;
    for (int c = -1; c < 3; ++c) {
      float& v = c < 0 ? g.depth[p] : g.normal[3 * p + std::size_t(c)];
      const float v0 = v, h = 1e-4f;  // each term is piecewise linear in v: exact unless a kink lies within h
      v = v0 + h;
      const double lp = losses::smoothness_loss(g, opt);
      const double up = double(v) - double(v0);
      v = v0 - h;
      const double lm = losses::smoothness_loss(g, opt);
      const double down = double(v0) - double(v);
      v = v0;
      const double fp = (lp - l0) / up, fm = (l0 - lm) / down;
      if (std::abs(fp - fm) > 0.1 * std::max(std::abs(fp), 1e-2)) continue;  // a kink within h: no derivative to compare
      const double ad = c < 0 ? ad_d[p] : ad_n[3 * p + std::size_t(c)];
      CHECK(ad == doctest::Approx(0.5 * (fp + fm)).epsilon(0.01).scale(1e-3));
      ++checked;
    }
  }
  CHECK(checked > 100);
}

TEST_CASE("smoothness gradient is the maps' backward of the loss adjoints") {
  const ds::Camera cam = front_camera(40, 40);
  const ds::TriangleMesh m = to_mesh(rotated(make_icosphere(0.6f, 2), 0.3f, 0.6f));
  losses::SmoothnessOptions opt;
  opt.depth_weight = 0.5f;
  opt.laplacian_weight = 0.0f;  // |∇²n| sits near its kinks everywhere on a sphere: not for central differences
  std::vector<float> grad(m.positions.size(), 0.0f);
  losses::GeometryMaps maps;
  const double loss = losses::smoothness_gradient(m, cam, grad.data(), opt, {}, &maps);
  const dr::Raster r = dr::rasterize(m, cam);
  CHECK(loss == doctest::Approx(losses::smoothness_loss(losses::geometry_maps(m, cam, r, opt), opt)));
  CHECK(loss == doctest::Approx(losses::smoothness_loss(maps, opt)));
  for (unsigned seed : {11u, 12u, 13u}) {
    const std::vector<float> dir = random_direction(m.positions.size(), seed);
    const double h = 1e-4;
    const double lp = losses::smoothness_loss(losses::geometry_maps(moved(m, dir, h), cam, r, opt), opt);
    const double lm = losses::smoothness_loss(losses::geometry_maps(moved(m, dir, -h), cam, r, opt), opt);
    const double fd = (lp - lm) / (2 * h), ad = dot(grad, dir);
    CAPTURE(seed);
    CHECK(ad == doctest::Approx(fd).epsilon(0.03));
  }
}
