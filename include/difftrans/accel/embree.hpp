// Host ray–triangle intersection with Embree 3: answers in float which
// triangle a ray hits (robust mode, so rays do not slip between adjacent
// triangles); the tracer then re-evaluates the hit on that triangle in its
// own scalar type. Input is validated before it reaches Embree, whose commit
// would silently drop primitives with NaN/Inf vertices.
#pragma once

#include <embree3/rtcore.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "difftrans/accel/ray_hit.hpp"
#include "difftrans/core/vec.hpp"

namespace difftrans::accel {

class EmbreeScene {
 public:
  // positions: x y z per vertex; indices: three per triangle. Throws
  // std::invalid_argument naming the first bad vertex or triangle.
  EmbreeScene(const float* positions, std::int32_t vertex_count, const std::int32_t* indices,
              std::int32_t triangle_count, const std::string& name = "mesh")
      : name_(name), vertex_count_(vertex_count), triangle_count_(triangle_count) {
    validate_positions(positions);
    for (std::int32_t f = 0; f < triangle_count; ++f)
      for (int k = 0; k < 3; ++k) {
        const std::int32_t i = indices[3 * f + k];
        if (i < 0 || i >= vertex_count)
          throw std::invalid_argument(name_ + ": triangle " + std::to_string(f) + " refers to vertex " +
                                      std::to_string(i) + ", but there are " + std::to_string(vertex_count) +
                                      " vertices");
      }
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw std::runtime_error("Embree: cannot create a device (error " + std::to_string(rtcGetDeviceError(nullptr)) + ")");
    rtcSetDeviceErrorFunction(device_, &EmbreeScene::on_error, this);
    scene_ = rtcNewScene(device_);
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), std::size_t(vertex_count)));
    auto* idx = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(std::uint32_t), std::size_t(triangle_count)));
    if (!v || !idx) throw std::runtime_error("Embree: cannot allocate buffers for " + name_ + ": " + error_);
    for (std::int64_t i = 0; i < 3 * std::int64_t(vertex_count); ++i) v[i] = positions[i];
    for (std::int64_t i = 0; i < 3 * std::int64_t(triangle_count); ++i) idx[i] = std::uint32_t(indices[i]);
    rtcCommitGeometry(geom);
    geometry_id_ = rtcAttachGeometry(scene_, geom);
    rtcReleaseGeometry(geom);
    commit();
  }

  ~EmbreeScene() {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
  }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // New vertex positions, same topology (e.g. after an optimizer step).
  void update_positions(const float* positions) {
    validate_positions(positions);
    RTCGeometry geom = rtcGetGeometry(scene_, geometry_id_);
    auto* v = static_cast<float*>(rtcGetGeometryBufferData(geom, RTC_BUFFER_TYPE_VERTEX, 0));
    for (std::int64_t i = 0; i < 3 * std::int64_t(vertex_count_); ++i) v[i] = positions[i];
    rtcUpdateGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(geom);
    commit();
  }

  // Closest hit along o + t d for t in [tnear, tfar]. Thread-safe. A ray
  // Embree would refuse (an origin or direction not finite, a negative or NaN
  // range) misses: Embree builds with assertions abort on one.
  RayHit intersect(const Vec3f& o, const Vec3f& d, float tnear = 0.0f,
                   float tfar = std::numeric_limits<float>::infinity()) const {
    if (!std::isfinite(o.x + o.y + o.z + d.x + d.y + d.z) || !(tnear >= 0.0f) || !(tfar >= 0.0f)) return RayHit{};
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    rh.ray.org_x = o.x;
    rh.ray.org_y = o.y;
    rh.ray.org_z = o.z;
    rh.ray.tnear = tnear;
    rh.ray.dir_x = d.x;
    rh.ray.dir_y = d.y;
    rh.ray.dir_z = d.z;
    rh.ray.time = 0.0f;
    rh.ray.tfar = tfar;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &context, &rh);
    RayHit h;
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
      h.prim = std::int32_t(rh.hit.primID);
      h.t = rh.ray.tfar;
      h.u = rh.hit.u;
      h.v = rh.hit.v;
    }
    return h;
  }

  std::int32_t vertex_count() const { return vertex_count_; }
  std::int32_t triangle_count() const { return triangle_count_; }

 private:
  void validate_positions(const float* positions) const {
    for (std::int32_t i = 0; i < vertex_count_; ++i)
      for (int k = 0; k < 3; ++k)
        if (!std::isfinite(positions[3 * i + k]))
          throw std::invalid_argument(name_ + ": vertex " + std::to_string(i) + " has a non-finite coordinate (" +
                                      std::to_string(positions[3 * i + k]) + ")");
  }

  void commit() {
    error_.clear();
    rtcCommitScene(scene_);
    if (!error_.empty()) throw std::runtime_error("Embree: building the BVH of " + name_ + " failed: " + error_);
  }

  static void on_error(void* self, RTCError code, const char* message) {
    auto* s = static_cast<EmbreeScene*>(self);
    s->error_ = "error " + std::to_string(int(code)) + (message ? std::string(": ") + message : std::string());
  }

  std::string name_;
  std::int32_t vertex_count_ = 0, triangle_count_ = 0;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  unsigned geometry_id_ = 0;
  std::string error_;
};

}  // namespace difftrans::accel
