// Pictures of a mesh with a colour per vertex (an error map, a label), for
// people to look at without a mesh viewer: the mesh rasterized (the closest
// triangle at each pixel centre), the three vertex colours blended by the
// perspective-correct barycentrics and darkened where the surface turns away
// from the viewer (by 0.35 + 0.65 |cos| of the angle between the triangle's
// normal and the view ray), so that the shape reads; and six cameras around
// a mesh that frame it whole; the six pictures and a colour bar as one sheet.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/io/contact_sheet.hpp"
#include "difftrans/io/png.hpp"
#include "difftrans/render/raster.hpp"
#include "difftrans/scene/camera.hpp"

namespace difftrans::render {

using VertexColour = std::array<std::uint8_t, 3>;

// The mesh (positions 3 per vertex, triangles 3 per face) seen by `camera`,
// coloured per vertex; `background` where no triangle covers a pixel centre.
// An 8-bit RGB image of the camera's size.
inline io::Image8 vertex_colour_picture(const std::vector<float>& positions, const std::vector<std::int32_t>& triangles,
                                        const std::vector<VertexColour>& colours, const scene::Camera& camera,
                                        VertexColour background = {40, 40, 48}) {
  if (colours.size() * 3 != positions.size())
    throw std::invalid_argument("vertex_colour_picture: one colour per vertex expected");
  const std::int32_t nv = std::int32_t(positions.size() / 3), nt = std::int32_t(triangles.size() / 3);
  const Raster r = rasterize(positions.data(), nv, triangles.data(), nt, camera);
  io::Image8 out{camera.width, camera.height, 3, std::vector<std::uint8_t>(std::size_t(r.pixels()) * 3)};
  const Vec3f eye = camera.position();
  for (int y = 0; y < r.height; ++y)
    for (int x = 0; x < r.width; ++x) {
      const std::size_t p = std::size_t(y) * std::size_t(r.width) + std::size_t(x);
      std::uint8_t* px = &out.data[3 * p];
      const std::int32_t t = r.triangle[p];
      if (t < 0) {
        std::copy(background.begin(), background.end(), px);
        continue;
      }
      const std::int32_t* tri = &triangles[3 * std::size_t(t)];
      Vec3f v[3];
      for (int k = 0; k < 3; ++k) {
        const float* q = &positions[3 * std::size_t(tri[k])];
        v[k] = Vec3f(q[0], q[1], q[2]);
      }
      const float w1 = r.b1[p], w2 = r.b2[p], w0 = 1.0f - w1 - w2;
      const Vec3f at = v[0] * w0 + v[1] * w1 + v[2] * w2;
      Vec3f n = glm::cross(v[1] - v[0], v[2] - v[0]);
      const float ln = glm::length(n), lv = glm::length(at - eye);
      const float facing = ln > 0.0f && lv > 0.0f ? std::fabs(glm::dot(n, at - eye)) / (ln * lv) : 1.0f;
      const float shade = 0.35f + 0.65f * facing;
      for (int c = 0; c < 3; ++c) {
        const float value = w0 * float(colours[std::size_t(tri[0])][std::size_t(c)]) +
                            w1 * float(colours[std::size_t(tri[1])][std::size_t(c)]) +
                            w2 * float(colours[std::size_t(tri[2])][std::size_t(c)]);
        px[c] = std::uint8_t(std::clamp(shade * value + 0.5f, 0.0f, 255.0f));
      }
    }
  return out;
}

// Six square cameras of `size` pixels around the mesh's bounding box, +Y up:
// from the front (+Z), the right (+X), the back (−Z), the left (−X), above
// (+Y) and below (−Y), each at a distance that keeps the box's bounding
// sphere inside a 30° field of view.
inline std::vector<scene::Camera> cameras_around(const std::vector<float>& positions, int size) {
  if (positions.size() < 3) throw std::invalid_argument("cameras_around: the mesh has no vertex");
  Vec3f lo(positions[0], positions[1], positions[2]), hi = lo;
  for (std::size_t i = 0; i + 2 < positions.size(); i += 3) {
    const Vec3f q(positions[i], positions[i + 1], positions[i + 2]);
    lo = glm::min(lo, q);
    hi = glm::max(hi, q);
  }
  const Vec3f centre = 0.5f * (lo + hi);
  const float radius = std::max(0.5f * glm::length(hi - lo), 1e-6f);
  const float fov = 30.0f * pi_v<float> / 180.0f;
  const float distance = radius / std::sin(0.5f * fov);
  std::vector<scene::Camera> cams;
  for (const Vec3f& dir : {Vec3f(0, 0, 1), Vec3f(1, 0, 0), Vec3f(0, 0, -1), Vec3f(-1, 0, 0), Vec3f(0, 1, 0),
                           Vec3f(0, -1, 0)})
    cams.push_back(scene::look_at_camera(centre + distance * dir, centre,
                                         std::fabs(dir.y) > 0.5f ? Vec3f(0, 0, -dir.y) : Vec3f(0, 1, 0), fov, size,
                                         size));
  return cams;
}

// The mesh from the six cameras_around it, `size` pixels each, in two rows
// of four: front, right, back, left, then above, below and a bar of the
// colour scale (`scale` of 0 at the bottom to 1 at the top), on a dark grey.
inline io::Image8 vertex_colour_sheet(const std::vector<float>& positions, const std::vector<std::int32_t>& triangles,
                                      const std::vector<VertexColour>& colours, int size,
                                      const std::function<VertexColour(float)>& scale) {
  std::vector<std::vector<io::Image8>> rows(2);
  for (const scene::Camera& cam : cameras_around(positions, size))
    rows[rows[0].size() < 4 ? 0 : 1].push_back(vertex_colour_picture(positions, triangles, colours, cam));
  io::Image8 bar{size, size, 3, std::vector<std::uint8_t>(std::size_t(size) * std::size_t(size) * 3, 40)};
  for (int y = 8; y < size - 8; ++y)
    for (int x = size / 2 - 12; x < size / 2 + 12; ++x) {
      const VertexColour c = scale(float(size - 8 - y) / float(size - 16));
      std::copy(c.begin(), c.end(), &bar.data[3 * (std::size_t(y) * std::size_t(size) + std::size_t(x))]);
    }
  rows[1].push_back(bar);
  io::SheetLayout layout;
  layout.tile_width = layout.tile_height = size;
  layout.rows = 2;
  layout.cols = 4;
  return io::compose_sheet(layout, rows);
}

}  // namespace difftrans::render
