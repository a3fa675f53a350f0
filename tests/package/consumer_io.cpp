// Uses the installed difftrans::io and difftrans::host_tracing: writes an
// octahedron as OBJ and reads it back, renders it as absorbing glass on the
// host (Embree or the portable BVH, whichever the installed build had),
// writes the picture as PNG and reads it back. argv[1]: a folder to write in.
#include <difftrans/io/image_file.hpp>
#include <difftrans/io/mesh_file.hpp>
#include <difftrans/render/passes.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

int main(int argc, char** argv) {
  namespace io = difftrans::io;
  namespace render = difftrans::render;
  using difftrans::Vec3f;
  using difftrans::Vec3i;
  if (argc != 2) {
    std::fprintf(stderr, "usage: consumer_io FOLDER\n");
    return 2;
  }
  const std::filesystem::path dir = argv[1];

  io::Mesh octahedron;
  octahedron.positions = {Vec3f(0.5f, 0, 0), Vec3f(-0.5f, 0, 0), Vec3f(0, 0.5f, 0),
                          Vec3f(0, -0.5f, 0), Vec3f(0, 0, 0.5f), Vec3f(0, 0, -0.5f)};
  octahedron.triangles = {Vec3i(0, 2, 4), Vec3i(2, 1, 4), Vec3i(1, 3, 4), Vec3i(3, 0, 4),
                          Vec3i(2, 0, 5), Vec3i(1, 2, 5), Vec3i(3, 1, 5), Vec3i(0, 3, 5)};
  io::write_mesh(dir / "octahedron.obj", octahedron);
  const io::Mesh mesh = io::read_mesh(dir / "octahedron.obj");
  if (mesh.positions.size() != 6 || mesh.triangles.size() != 8) {
    std::fprintf(stderr, "octahedron.obj read back with %zu vertices, %zu triangles\n", mesh.positions.size(),
                 mesh.triangles.size());
    return 1;
  }

  std::vector<float> positions;
  std::vector<std::int32_t> triangles;
  for (const Vec3f& p : mesh.positions) positions.insert(positions.end(), {p.x, p.y, p.z});
  for (const Vec3i& t : mesh.triangles) triangles.insert(triangles.end(), {t.x, t.y, t.z});
  render::HostScene scene(std::move(positions), std::move(triangles), "octahedron");
  scene.ior = 1.5f;
  scene.set_homogeneous_absorption(Vec3f(2.0f));
  scene.set_constant_environment(Vec3f(1.0f));
  const int size = 16;
  const auto cam = difftrans::scene::look_at_camera(Vec3f(0, 0, 3), Vec3f(0.0f), Vec3f(0, 1, 0), 0.5f, size, size);
  const std::vector<float> pixels = render::render_image<float>(scene, cam);

  io::Image image(size, size);
  image.rgb = pixels;
  io::write_image(dir / "octahedron.png", image);
  const io::Image back = io::read_image(dir / "octahedron.png");
  const auto red = [&](const io::Image& im, int x, int y) { return im.rgb[3 * (std::size_t(y) * size + x)]; };
  const float centre = red(back, size / 2, size / 2), corner = red(back, 0, 0);
  std::printf("octahedron rendered on the host (%s): centre %.3f, corner %.3f (read back from PNG)\n",
#if DIFFTRANS_HAVE_EMBREE
              "Embree",
#else
              "portable BVH",
#endif
              double(centre), double(corner));
  // the background is the environment; light through the glass is absorbed
  return back.width == size && back.height == size && corner > 0.95f && centre < 0.9f ? 0 : 1;
}
