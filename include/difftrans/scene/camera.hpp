// Pinhole camera of the NeRF-synthetic convention (4x4 camera-to-world, OpenGL
// axes: looks down -Z, +Y up): float ray generation, projection generic over S.
#pragma once

#include <cmath>

#include "difftrans/ad/glm.hpp"
#include "difftrans/core/constants.hpp"

namespace difftrans::scene {

// Pixel coordinates are continuous: pixel (x, y) (column x from the left,
// row y from the top) covers [x, x+1) x [y, y+1), its centre is (x+0.5, y+0.5).
// The principal point (cx, cy) is in the same coordinates; (w/2, h/2) is the
// image centre. A camera-space point q maps to
//   px = cx + fx * q.x / (-q.z),   py = cy - fy * q.y / (-q.z).

struct Ray {
  Vec3f origin;
  Vec3f direction;  // unit
};

template <class S>
struct Projection {
  Vec2<S> pixel;  // continuous pixel coordinates (px, py); zero when !valid
  S depth;        // distance along the viewing axis, -q.z
  bool valid;     // the point lies in front of the camera (depth > 0)
};

struct Camera {
  Mat4<float> camera_to_world{1.0f};
  Mat4<float> world_to_camera{1.0f};
  float fx = 1.0f, fy = 1.0f;  // focal lengths in pixels
  float cx = 0.5f, cy = 0.5f;  // principal point in pixels
  int width = 1, height = 1;

  // From the camera-to-world matrix and the intrinsics (fl_x, fl_y, cx, cy).
  static Camera from_intrinsics(const Mat4<float>& to_world, float fl_x, float fl_y, float cx, float cy, int w,
                                int h) {
    Camera c;
    c.camera_to_world = to_world;
    c.world_to_camera = glm::inverse(to_world);
    c.fx = fl_x;
    c.fy = fl_y;
    c.cx = cx;
    c.cy = cy;
    c.width = w;
    c.height = h;
    return c;
  }

  // NeRF-synthetic: horizontal field of view camera_angle_x (radians), square
  // pixels, principal point at the image centre.
  static Camera from_fov_x(const Mat4<float>& to_world, float camera_angle_x, int w, int h) {
    const float f = float(0.5 * w / std::tan(0.5 * double(camera_angle_x)));
    return from_intrinsics(to_world, f, f, 0.5f * float(w), 0.5f * float(h), w, h);
  }

  // Vertical field of view fov_y (radians), square pixels, centred.
  static Camera from_fov_y(const Mat4<float>& to_world, float fov_y, int w, int h) {
    const float f = float(0.5 * h / std::tan(0.5 * double(fov_y)));
    return from_intrinsics(to_world, f, f, 0.5f * float(w), 0.5f * float(h), w, h);
  }

  DT_HOST_DEVICE Vec3f position() const { return Vec3f(camera_to_world[3]); }

  // The ray through continuous pixel coordinates (px, py).
  DT_HOST_DEVICE Ray ray_through(float px, float py) const {
    const Vec3f dc((px - cx) / fx, -(py - cy) / fy, -1.0f);
    const Vec3f dw = Vec3f(camera_to_world * Vec4<float>(dc, 0.0f));
    return Ray{position(), dw / sqrt(glm::dot(dw, dw))};
  }

  // The ray through pixel (x, y) at sub-pixel offset (u, v) in [0, 1); the
  // default is the pixel centre.
  DT_HOST_DEVICE Ray generate_ray(int x, int y, float u = 0.5f, float v = 0.5f) const {
    return ray_through(float(x) + u, float(y) + v);
  }

  // A world point in camera coordinates (OpenGL axes), generic over S.
  template <class S>
  DT_HOST_DEVICE Vec3<S> to_camera(const Vec3<S>& p) const {
    const Mat4<float>& m = world_to_camera;
    Vec3<S> q;
    for (int r = 0; r < 3; ++r) q[r] = p.x * m[0][r] + p.y * m[1][r] + p.z * m[2][r] + m[3][r];
    return q;
  }

  // Pixel coordinates and depth of a world point, generic over S. Points at
  // or behind the camera plane are !valid (pixel zero, never inf or NaN).
  template <class S>
  DT_HOST_DEVICE Projection<S> project(const Vec3<S>& p) const {
    const Vec3<S> q = to_camera(p);
    Projection<S> r;
    r.depth = -q.z;
    r.valid = r.depth > 0;
    if (r.valid) {
      const S inv = S(1) / r.depth;
      r.pixel = Vec2<S>(cx + fx * q.x * inv, cy - fy * q.y * inv);
    } else {
      r.pixel = Vec2<S>(S(0), S(0));
    }
    return r;
  }

  // OpenGL-style homogeneous clip coordinates for a rasterizer, generic over
  // S: clip.w = depth, ndc = clip.xyz / clip.w with ndc.x = 2 px / width - 1,
  // ndc.y = 2 py / height - 1 (row 0 at ndc.y = -1, as nvdiffrast stores
  // images), ndc.z from -1 at depth `near` to +1 at depth `far`.
  template <class S>
  DT_HOST_DEVICE Vec4<S> to_clip(const Vec3<S>& p, float near, float far) const {
    const Vec3<S> q = to_camera(p);
    const S depth = -q.z;
    const float sx = 2.0f * fx / float(width), ox = 2.0f * cx / float(width) - 1.0f;
    const float sy = 2.0f * fy / float(height), oy = 2.0f * cy / float(height) - 1.0f;
    const float a = (far + near) / (far - near), b = 2.0f * far * near / (far - near);
    return Vec4<S>(sx * q.x + ox * depth, oy * depth - sy * q.y, a * depth - b, depth);
  }
};

// A camera-to-world matrix from the 16 numbers of a NeRF transform_matrix
// listed row by row (as the JSON writes it).
inline Mat4<float> matrix_from_rows(const float rows[16]) {
  Mat4<float> m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[c][r] = rows[4 * r + c];  // GLM is column-major
  return m;
}

// Camera-to-world matrix of a camera at `eye` looking at `target`, with `up`
// as close to the image's +Y as possible. When the view direction is parallel
// to `up` another up vector is used (the image is then turned arbitrarily).
inline Mat4<float> look_at_matrix(const Vec3f& eye, const Vec3f& target, const Vec3f& up) {
  const Vec3f z = glm::normalize(eye - target);  // the camera looks down -Z
  Vec3f x = glm::cross(up, z);
  if (glm::length(x) < 1e-6f * glm::length(up)) x = glm::cross(std::fabs(z.y) < 0.9f ? Vec3f(0, 1, 0) : Vec3f(0, 0, 1), z);
  x = glm::normalize(x);
  const Vec3f y = glm::cross(z, x);
  Mat4<float> m(1.0f);
  m[0] = Vec4<float>(x, 0.0f);
  m[1] = Vec4<float>(y, 0.0f);
  m[2] = Vec4<float>(z, 0.0f);
  m[3] = Vec4<float>(eye, 1.0f);
  return m;
}

// A look-at camera with vertical field of view fov_y (radians).
inline Camera look_at_camera(const Vec3f& eye, const Vec3f& target, const Vec3f& up, float fov_y, int w, int h) {
  return Camera::from_fov_y(look_at_matrix(eye, target, up), fov_y, w, h);
}

// The benchmark scenes' camera (docs/benchmark-scenes.md): on the sphere of radius 3
// in direction `dir` from the origin, looking at the origin, +Y up, vertical
// field of view 40 degrees.
inline constexpr float protocol_camera_radius = 3.0f;
inline constexpr float protocol_camera_fov_y = 40.0f * pi_v<float> / 180.0f;
inline Camera protocol_camera(const Vec3f& dir, int w = 256, int h = 256) {
  return look_at_camera(protocol_camera_radius * glm::normalize(dir), Vec3f(0.0f), Vec3f(0, 1, 0),
                        protocol_camera_fov_y, w, h);
}

}  // namespace difftrans::scene
