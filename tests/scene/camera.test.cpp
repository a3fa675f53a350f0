// Pinhole camera: the NeRF convention (the centre ray is the camera's -Z),
// field-of-view edges, projection of ray points back to their pixel, the
// look-at / protocol camera, clip coordinates, and projection derivatives.
#include "scene/scene_check.hpp"

using namespace dt_test;
using scene::Camera;

namespace {

double angle_between(const Vec3f& a, const Vec3f& b) {
  const Vec3d x = glm::normalize(Vec3d(a)), y = glm::normalize(Vec3d(b));
  return std::atan2(glm::length(glm::cross(x, y)), glm::dot(x, y));
}

// A rigid camera-to-world matrix with a translation, from a NeRF-style row list.
Mat4<float> some_pose() {
  const Vec3d axis = glm::normalize(Vec3d(0.3, 1.0, -0.4));
  const double a = 0.8, c = std::cos(a), s = std::sin(a);
  // Rodrigues' rotation, written as rows
  double R[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R[i][j] = (i == j ? c : 0.0) + (1 - c) * axis[i] * axis[j];
  R[0][1] -= s * axis.z, R[0][2] += s * axis.y, R[1][0] += s * axis.z;
  R[1][2] -= s * axis.x, R[2][0] -= s * axis.y, R[2][1] += s * axis.x;
  const float rows[16] = {float(R[0][0]), float(R[0][1]), float(R[0][2]), 0.5f,
                          float(R[1][0]), float(R[1][1]), float(R[1][2]), -1.0f,
                          float(R[2][0]), float(R[2][1]), float(R[2][2]), 2.5f,
                          0.0f,           0.0f,           0.0f,           1.0f};
  return scene::matrix_from_rows(rows);
}

std::vector<Camera> cameras() {
  return {Camera::from_fov_x(some_pose(), 0.6911112f, 64, 48),  // the NeRF-synthetic angle
          Camera::from_intrinsics(some_pose(), 70.0f, 64.0f, 30.0f, 27.0f, 64, 48),
          scene::protocol_camera(Vec3f(0.3f, 0.5f, 0.8f), 33, 33), scene::protocol_camera(Vec3f(0, 1, 0))};
}

}  // namespace

TEST_CASE("matrix_from_rows reads the NeRF transform_matrix row by row") {
  const Mat4<float> m = some_pose();
  CHECK(m[3][0] == 0.5f);  // translation column
  CHECK(m[3][1] == -1.0f);
  CHECK(m[3][2] == 2.5f);
  const Camera cam = Camera::from_fov_x(m, 0.7f, 10, 10);
  CHECK(cam.position() == Vec3f(0.5f, -1.0f, 2.5f));
}

TEST_CASE("NeRF convention: the centre ray is the camera's -Z axis, +Y is up") {
  for (const Camera& cam : cameras()) {
    if (cam.cx != 0.5f * cam.width) continue;  // centred cameras only
    const Vec3f minus_z = -Vec3f(cam.camera_to_world[2]);
    const Vec3f plus_y = Vec3f(cam.camera_to_world[1]), plus_x = Vec3f(cam.camera_to_world[0]);
    const scene::Ray r = cam.ray_through(0.5f * cam.width, 0.5f * cam.height);
    CHECK(angle_between(r.direction, minus_z) < 1e-6);
    CHECK(r.origin == cam.position());
    CHECK(std::abs(glm::length(r.direction) - 1.0f) < 1e-6f);
    if (cam.width % 2 == 1) {  // odd size: the centre pixel's centre
      const scene::Ray c = cam.generate_ray(cam.width / 2, cam.height / 2);
      CHECK(angle_between(c.direction, minus_z) < 1e-6);
    }
    // row 0 is the top of the image, column 0 its left
    const scene::Ray up = cam.generate_ray(cam.width / 2, 0), left = cam.generate_ray(0, cam.height / 2);
    CHECK(glm::dot(up.direction, plus_y) > 0.1f);
    CHECK(glm::dot(left.direction, plus_x) < -0.1f);
  }
}

TEST_CASE("field-of-view edges") {
  const float angle_x = 0.6911112f;
  const Camera nerf = Camera::from_fov_x(some_pose(), angle_x, 64, 48);
  const Vec3f axis = -Vec3f(nerf.camera_to_world[2]);
  CHECK(std::abs(angle_between(nerf.ray_through(0.0f, 24.0f).direction, axis) - 0.5 * angle_x) < 1e-6);
  CHECK(std::abs(angle_between(nerf.ray_through(64.0f, 24.0f).direction, axis) - 0.5 * angle_x) < 1e-6);
  // the left and right edges span the whole angle
  CHECK(std::abs(angle_between(nerf.ray_through(0.0f, 24.0f).direction, nerf.ray_through(64.0f, 24.0f).direction) -
                 angle_x) < 1e-6);
  // the protocol camera: vertical field of view 40 degrees
  const Camera p = scene::protocol_camera(Vec3f(1, 0.2f, 0.4f), 256, 256);
  const double half = 20.0 * pi_v<double> / 180.0;
  const Vec3f paxis = -Vec3f(p.camera_to_world[2]);
  CHECK(std::abs(angle_between(p.ray_through(128.0f, 0.0f).direction, paxis) - half) < 1e-6);
  CHECK(std::abs(angle_between(p.ray_through(128.0f, 256.0f).direction, paxis) - half) < 1e-6);
  // non-square image: the vertical angle stays, the horizontal one widens
  const Camera wide = scene::look_at_camera(Vec3f(0, 0, 3), Vec3f(0), Vec3f(0, 1, 0), 0.5f, 200, 100);
  CHECK(std::abs(angle_between(wide.ray_through(100.0f, 0.0f).direction, Vec3f(0, 0, -1)) - 0.25) < 1e-6);
  CHECK(std::abs(angle_between(wide.ray_through(0.0f, 50.0f).direction, Vec3f(0, 0, -1)) -
                 std::atan(2.0 * std::tan(0.25))) < 1e-6);
}

TEST_CASE("the protocol camera: radius 3, looking at the origin, +Y up") {
  for (const Vec3f dir : {Vec3f(0.3f, 0.5f, 0.8f), Vec3f(-1, 0.05f, 0), Vec3f(0, 1, 0), Vec3f(0, -1, 0)}) {
    CAPTURE(dir);
    const Camera cam = scene::protocol_camera(dir);
    CHECK(std::abs(glm::length(cam.position()) - 3.0f) < 1e-5f);
    const scene::Ray c = cam.ray_through(128.0f, 128.0f);
    CHECK(glm::length(c.origin + 3.0f * c.direction) < 1e-5f);  // the centre ray passes the origin
    const Vec3f x = Vec3f(cam.camera_to_world[0]), y = Vec3f(cam.camera_to_world[1]);
    CHECK(std::abs(glm::length(x) - 1.0f) < 1e-6f);
    CHECK(std::abs(glm::dot(x, y)) < 1e-6f);
    if (std::abs(dir.y) < 0.99f * glm::length(dir)) {
      CHECK(std::abs(x.y) < 1e-6f);  // the image's horizontal is level
      CHECK(y.y > 0.0f);             // +Y up
    }
    const Vec2<float> centre = cam.project(Vec3f(0.0f)).pixel;
    CHECK(std::abs(centre.x - 128.0f) < 1e-3f);
    CHECK(std::abs(centre.y - 128.0f) < 1e-3f);
  }
}

TEST_CASE_TEMPLATE("project(ray(pixel)) returns the pixel", S, DT_ALL_SCALARS) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  for (const Camera& cam : cameras()) {
    for (int k = 0; k < 50; ++k) {
      const int x = int(u01(rng) * cam.width), y = int(u01(rng) * cam.height);
      const float u = u01(rng), v = u01(rng);
      const scene::Ray r = cam.generate_ray(x, y, u, v);
      const float t = 0.5f + 5.0f * u01(rng);
      const Vec3f pf = r.origin + t * r.direction;
      const scene::Projection<S> p = cam.project(Vec3<S>(S(pf.x), S(pf.y), S(pf.z)));
      CHECK(p.valid);
      CHECK(std::abs(double(ad::value_of(p.pixel.x)) - (x + u)) < 2e-3);
      CHECK(std::abs(double(ad::value_of(p.pixel.y)) - (y + v)) < 2e-3);
      const Vec3f axis = -Vec3f(cam.camera_to_world[2]);
      CHECK(std::abs(double(ad::value_of(p.depth)) - t * glm::dot(r.direction, axis)) < 1e-4 * (1 + t));
      // clip coordinates agree with the pixel
      const Vec4<S> c = cam.to_clip(Vec3<S>(S(pf.x), S(pf.y), S(pf.z)), 0.1f, 20.0f);
      const double w = double(ad::value_of(c.w));
      CHECK(std::abs(w - double(ad::value_of(p.depth))) < 1e-5 * (1 + w));
      CHECK(std::abs((double(ad::value_of(c.x)) / w + 1) * 0.5 * cam.width - (x + u)) < 2e-3);
      CHECK(std::abs((double(ad::value_of(c.y)) / w + 1) * 0.5 * cam.height - (y + v)) < 2e-3);
    }
  }
}

TEST_CASE("clip depth spans [-1, 1] between near and far; points behind are invalid") {
  const Camera cam = scene::look_at_camera(Vec3f(0, 0, 3), Vec3f(0), Vec3f(0, 1, 0), 0.7f, 32, 32);
  const Vec4<double> n = cam.to_clip(Vec3d(0.1, 0.2, 3 - 0.5), 0.5f, 10.0f);
  const Vec4<double> f = cam.to_clip(Vec3d(0.1, 0.2, 3 - 10.0), 0.5f, 10.0f);
  CHECK(std::abs(n.z / n.w + 1) < 1e-6);
  CHECK(std::abs(f.z / f.w - 1) < 1e-6);
  for (const Vec3d& q : {Vec3d(0, 0, 3), Vec3d(0.5, 0.1, 4), Vec3d(1, 1, 3)}) {
    const scene::Projection<double> p = cam.project(q);
    CHECK_FALSE(p.valid);
    CHECK(std::isfinite(p.pixel.x));
    CHECK(std::isfinite(p.pixel.y));
  }
}

TEST_CASE_TEMPLATE("projection derivatives match central differences", S, DT_AD_SCALARS) {
  const Camera cam = Camera::from_intrinsics(some_pose(), 70.0f, 64.0f, 30.0f, 27.0f, 64, 48);
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  for (int k = 0; k < 10; ++k) {
    const scene::Ray r = cam.generate_ray(int(u01(rng) * 64), int(u01(rng) * 48), u01(rng), u01(rng));
    const Vec3d p0 = Vec3d(r.origin) + (1.0 + 3.0 * u01(rng)) * Vec3d(r.direction);
    for (int comp = 0; comp < 3; ++comp)
      for (int out = 0; out < 3; ++out) {
        CAPTURE(k);
        CAPTURE(comp);
        CAPTURE(out);
        const auto f = [&](auto x) {
          using R = decltype(x);
          Vec3<R> p(R(p0.x), R(p0.y), R(p0.z));
          p[comp] = x;
          const scene::Projection<R> pr = cam.project(p);
          return out < 2 ? pr.pixel[out] : pr.depth;
        };
        const double d = derivative<S>(f, p0[comp]);
        const double fd = central_difference(f, p0[comp]);
        CHECK(std::abs(d - fd) <= tol<S>() * 10 * std::max(1.0, std::abs(fd)));
      }
  }
}
