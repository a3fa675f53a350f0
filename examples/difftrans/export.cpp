// difftrans export: a reconstruction (the output folder of difftrans
// reconstruct) or a given mesh + material (+ environment, cameras) written in
// standard formats: glTF 2.0 binary, a Mitsuba 3 scene, or PLY / OBJ with the
// material JSON beside it. Everything goes into the folder --out (written as
// OUT.partial and moved into place when complete).
#include "export.hpp"
#include "output_folder.hpp"

#include <array>
#include <charconv>
#include <cstdlib>
#include <cstdint>
#include <memory>
#include <sstream>

#include "difftrans/render/host_scene.hpp"
#include "difftrans/scene/mesh.hpp"
#include "stage_output.hpp"

namespace difftrans::cli {

std::vector<Vec3f> export_vertex_normals(const io::Mesh& mesh) {
  const scene::TriangleMesh m(io::flat_positions(mesh), io::flat_triangles(mesh));
  std::vector<Vec3f> normals(mesh.positions.size());
  for (std::size_t v = 0; v < normals.size(); ++v) {
    const Vec3f n(m.vertex_normals[3 * v], m.vertex_normals[3 * v + 1], m.vertex_normals[3 * v + 2]);
    normals[v] = glm::dot(n, n) > 0.5f ? n : Vec3f(0.0f, 1.0f, 0.0f);
  }
  return normals;
}

namespace {

// Whether p lies inside the closed mesh: the first surface that rays from p
// meet faces away from p (its outward normal points along the ray); the
// majority of three rays in unrelated directions decides.
class InsideTest {
 public:
  explicit InsideTest(const io::Mesh& mesh) : mesh_(mesh) {
    for (const Vec3f& p : mesh.positions) positions_.insert(positions_.end(), {p.x, p.y, p.z});
    for (const Vec3i& t : mesh.triangles) triangles_.insert(triangles_.end(), {t.x, t.y, t.z});
    accel_ = std::make_unique<render::HostAccel>(positions_.data(), std::int32_t(mesh.positions.size()),
                                                 triangles_.data(), std::int32_t(mesh.triangles.size()), "export");
  }
  bool inside(const Vec3f& p) const {
    static const std::array<Vec3f, 3> dirs = {glm::normalize(Vec3f(0.5377f, 0.8346f, 0.1189f)),
                                              glm::normalize(Vec3f(-0.6912f, -0.1537f, 0.7061f)),
                                              glm::normalize(Vec3f(0.2178f, -0.5629f, -0.7972f))};
    int votes = 0;
    for (const Vec3f& d : dirs) {
      const accel::RayHit h = accel_->intersect(p, d);
      if (!h.hit()) continue;
      const Vec3i& t = mesh_.triangles[std::size_t(h.prim)];
      const Vec3f& a = mesh_.positions[std::size_t(t.x)];
      const Vec3f n = glm::cross(mesh_.positions[std::size_t(t.y)] - a, mesh_.positions[std::size_t(t.z)] - a);
      votes += glm::dot(n, d) > 0.0f;
    }
    return votes >= 2;
  }

 private:
  const io::Mesh& mesh_;
  std::vector<float> positions_;
  std::vector<std::int32_t> triangles_;
  std::unique_ptr<render::HostAccel> accel_;
};

// The double closest to the shortest decimal that reads back as x (0.4f ->
// 0.4, not 0.4000000059604645): what the material file said.
double float_as_double(float x) {
  char b[32];
  const auto r = std::to_chars(b, b + sizeof(b) - 1, x);
  *r.ptr = '\0';
  return std::strtod(b, nullptr);
}

// sigma of the grid at p, trilinear between its vertices, 0 outside its box
// (the format of io/material.hpp, as scene/absorption.hpp renders it).
Vec3d grid_sigma(const io::AbsorptionGrid& g, const Vec3f& p) {
  Vec3d t;
  Vec3i cell;
  for (int a = 0; a < 3; ++a) {
    const double x = (double(p[a]) - g.lo[a]) / (double(g.hi[a]) - g.lo[a]) * (g.res[a] - 1);
    if (!(x >= 0.0 && x <= g.res[a] - 1)) return Vec3d(0.0);
    cell[a] = std::min(int(x), g.res[a] - 2);
    t[a] = x - cell[a];
  }
  Vec3d sigma(0.0);
  for (int corner = 0; corner < 8; ++corner) {
    const int di = corner & 1, dj = (corner >> 1) & 1, dk = (corner >> 2) & 1;
    const double w = (di ? t.x : 1 - t.x) * (dj ? t.y : 1 - t.y) * (dk ? t.z : 1 - t.z);
    for (int c = 0; c < 3; ++c) sigma[c] += w * g.sigma[g.index(cell.x + di, cell.y + dj, cell.z + dk, c)];
  }
  return sigma;
}

}  // namespace

AbsorptionSummary summarize_absorption(const io::Mesh& mesh, const io::Material& material) {
  AbsorptionSummary s;
  s.type = io::to_string(material.absorption);
  if (material.absorption == io::AbsorptionType::none) {
    s.how = "no absorption (clear)";
    return s;
  }
  if (material.absorption == io::AbsorptionType::homogeneous) {
    for (int c = 0; c < 3; ++c) s.sigma[c] = float_as_double(material.sigma[c]);
    s.how = "homogeneous absorption";
    return s;
  }
  // a grid: the mean of its sigma over the object's volume, sampled at the
  // centres of an n^3 lattice of cells over the mesh's box
  const io::AbsorptionGrid& g = material.grid;
  const io::Box box = io::bounding_box(mesh);
  const InsideTest test(mesh);
  constexpr int n = absorption_samples_per_axis;
  Vec3d sum(0.0);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const Vec3d f((i + 0.5) / n, (j + 0.5) / n, (k + 0.5) / n);
        const Vec3f p(box.lo + f * box.size());
        ++s.samples_total;
        if (!test.inside(p)) continue;
        sum += grid_sigma(g, p);
        ++s.samples_used;
      }
  const std::string grid = "heterogeneous absorption grid (" + std::to_string(g.res.x) + " x " +
                           std::to_string(g.res.y) + " x " + std::to_string(g.res.z) + ")";
  if (s.samples_used > 0) {
    s.sigma = sum / double(s.samples_used);
    s.how = grid + " averaged over the object's volume: its trilinear sigma at the " + std::to_string(s.samples_used) +
            " of " + std::to_string(s.samples_total) + " points of a " + std::to_string(n) + "^3 lattice over the "
            "mesh's box that lie inside the mesh";
  } else {
    Vec3d all(0.0);
    for (std::size_t v = 0; v < g.vertex_count(); ++v)
      for (int c = 0; c < 3; ++c) all[c] += g.sigma[3 * v + std::size_t(c)];
    s.sigma = all / double(g.vertex_count());
    s.how = grid + " averaged over all its " + std::to_string(g.vertex_count()) +
            " vertices (no lattice point lies inside the mesh)";
  }
  return s;
}

namespace {

namespace fs = std::filesystem;

struct ExportOptions {
  std::string recon, format, out;
  std::string mesh, env, scene;
  MaterialOptions material;
  std::string split = "test";
  std::string mesh_format = "ply";
  int max_depth = 16, spp = 256;
  bool overwrite = false;
};

bool material_given(const MaterialOptions& m) {
  return !m.material_file.empty() || m.ior || !m.absorption.empty() || !m.absorption_grid.empty();
}

// The scene directory reconstruct.json records (relative paths are tried
// from the working directory, then from the reconstruction's parent).
fs::path recorded_scene(const fs::path& recon) {
  const fs::path record = recon / "reconstruct.json";
  if (!fs::exists(record)) {
    warn(record.string() + " not found: no scene cameras (pass --scene)");
    return {};
  }
  const io::Json j = io::read_json(record);
  if (!j.is_object() || !j.contains("scene") || !j["scene"].is_string()) {
    warn(record.string() + " records no \"scene\": no scene cameras (pass --scene)");
    return {};
  }
  const fs::path scene = j["scene"].get<std::string>();
  std::error_code ec;
  if (fs::is_directory(scene, ec)) return scene;
  if (scene.is_relative() && fs::is_directory(recon.parent_path() / scene, ec)) return recon.parent_path() / scene;
  warn(record.string() + ": the scene it records, " + scene.string() + ", is not a directory here: no scene cameras "
       "(pass --scene)");
  return {};
}

ExportInput gather(const ExportOptions& o) {
  ExportInput in;
  in.max_depth = o.max_depth;
  in.spp = o.spp;
  in.mesh_format = o.mesh_format;
  const fs::path recon = o.recon;
  std::error_code ec;
  if (!o.recon.empty() && !fs::is_directory(recon, ec))
    throw io::Error(recon, fs::exists(recon, ec) ? "is not a directory (expected an output folder of difftrans "
                                                   "reconstruct)"
                                                 : "reconstruction folder not found");
  if (o.recon.empty() && o.mesh.empty())
    throw CLI::ValidationError("give RECON_DIR (an output folder of difftrans reconstruct) or --mesh");

  // mesh: --mesh, else stage 2's, else stage 1's
  if (!o.mesh.empty()) {
    in.mesh_source = o.mesh;
  } else if (fs::is_regular_file(recon / "mesh_stage2.obj", ec)) {
    in.mesh_source = recon / "mesh_stage2.obj";
  } else if (fs::is_regular_file(recon / "mesh_stage1.obj", ec)) {
    in.mesh_source = recon / "mesh_stage1.obj";
    warn((recon / "mesh_stage2.obj").string() + " not found (stage 2, materials, has not run): exporting the stage-1 "
         "mesh " + in.mesh_source.string());
  } else {
    throw io::Error(recon, "no reconstructed mesh here (neither mesh_stage2.obj nor mesh_stage1.obj): run difftrans "
                           "reconstruct --stages geometry,materials first, or pass --mesh");
  }
  in.mesh = load_mesh(in.mesh_source);

  // material: the options, else stage 2's, else a default
  if (material_given(o.material)) {
    in.material = o.material.resolve();
    in.material_source = o.material.material_file.empty() ? "command-line options" : o.material.material_file;
    if (!o.recon.empty() && fs::is_regular_file(recon / "material_stage2.json", ec))
      progress("export: the material of the options replaces " + (recon / "material_stage2.json").string());
  } else if (!o.recon.empty() && fs::is_regular_file(recon / "material_stage2.json", ec)) {
    in.material = io::read_material(recon / "material_stage2.json");
    in.material_source = (recon / "material_stage2.json").string();
  } else if (!o.recon.empty()) {
    in.material.ior = 1.5;
    in.material_source = "default: IoR 1.5, no absorption (stage 2 has not run)";
    warn((recon / "material_stage2.json").string() + " not found (stage 2, materials, has not run): IoR 1.5 and no "
         "absorption; pass --ior or --material to choose");
  } else {
    throw CLI::ValidationError("give --material or --ior with --mesh");
  }

  if (o.format != "mitsuba") return in;

  // environment: --env, else the one reconstruct recovered
  if (!o.env.empty()) {
    in.env = load_environment(o.env);
  } else if (!o.recon.empty() && fs::is_regular_file(recovered_map(recon), ec)) {
    in.env = load_environment(recovered_map(recon).string());
    if (fs::exists(recon / "radiance_field.json", ec))
      warn((recon / "radiance_field.json").string() + ": Mitsuba gets the near-field environment as its panorama "
           "from the object's centre, " + recovered_map(recon).filename().string());
  } else {
    throw io::Error(o.recon.empty() ? fs::path("--env") : recon / "envmap.hdr",
                    o.recon.empty() ? "mitsuba needs an environment: pass --env"
                                    : "no recovered environment: run difftrans reconstruct --stages environment, or "
                                      "pass --env");
  }

  // cameras: --scene, else the scene reconstruct.json records
  in.scene = !o.scene.empty() ? fs::path(o.scene) : !o.recon.empty() ? recorded_scene(recon) : fs::path();
  if (!in.scene.empty()) {
    io::LoadOptions lo;
    lo.read_pixels = false;
    const io::Scene scene = io::load_scene(in.scene, lo);
    for (const auto& w : scene.warnings) warn(w);
    const std::vector<const io::Split*> splits =
        o.split == "all" ? std::vector<const io::Split*>{&scene.train, &scene.test}
                         : std::vector<const io::Split*>{o.split == "train" ? &scene.train : &scene.test};
    for (const io::Split* s : splits)
      for (const io::Frame& f : s->frames)
        if (!f.environment_only) in.cameras.push_back(f);
    if (in.cameras.empty()) throw io::Error(in.scene, "the scene has no " + o.split + " views of the object");
  } else {
    warn("no scene cameras: the Mitsuba scene has no sensor (Mitsuba then adds a default one)");
  }
  return in;
}

// PLY / OBJ: the mesh and material.json (with its grid file) beside it.
io::Json write_mesh_and_material(const ExportInput& in, const fs::path& dir, const std::string& format) {
  const std::string mesh_name = "mesh." + format;
  io::write_mesh(dir / mesh_name, in.mesh);
  io::Material m = in.material;
  if (m.absorption == io::AbsorptionType::grid) m.grid_file = "absorption_grid.json";
  io::write_material(dir / "material.json", m);
  io::Json j = io::Json::object();
  j["mesh"] = mesh_name;
  j["material"] = "material.json";
  if (m.absorption == io::AbsorptionType::grid) j["absorption_grid"] = m.grid_file;
  return j;
}

void run(const ExportOptions& o) {
  const ExportInput in = gather(o);
  const AbsorptionSummary absorption = summarize_absorption(in.mesh, in.material);
  if (absorption.type == "grid" && o.format != "ply" && o.format != "obj")
    progress("export: " + o.format + " holds one absorption coefficient: " + absorption.how + ", sigma = (" +
             fixed(absorption.sigma.x, 4) + ", " + fixed(absorption.sigma.y, 4) + ", " + fixed(absorption.sigma.z, 4) +
             ")");
  OutputDir out(o.out, o.overwrite,
                {o.recon, o.mesh, o.env, o.scene, o.material.material_file, o.material.absorption_grid});
  io::Json files;
  if (o.format == "gltf") files = write_gltf(in, absorption, out.path() / "object.glb");
  else if (o.format == "mitsuba") files = write_mitsuba(in, absorption, out.path());
  else files = write_mesh_and_material(in, out.path(), o.format);

  io::Json result = io::Json::object();
  result["format"] = o.format;
  result["out"] = out.final_path().string();
  result["files"] = files;
  result["mesh_source"] = in.mesh_source.string();
  result["material_source"] = in.material_source;
  result["vertices"] = in.mesh.positions.size();
  result["triangles"] = in.mesh.triangles.size();
  result["ior"] = in.material.ior;
  result["absorption"] = {{"type", absorption.type},
                          {"sigma", {absorption.sigma.x, absorption.sigma.y, absorption.sigma.z}},
                          {"how", absorption.how}};
  if (o.format == "mitsuba") {
    result["sensors"] = in.cameras.size();
    if (!in.scene.empty()) result["scene"] = in.scene.string();
  }
  io::write_json(out.path() / "export.json", result);
  out.commit();
  progress("export: wrote " + out.final_path().string());
  emit_json(result, std::nullopt);
}

}  // namespace

void add_export(CLI::App& app) {
  auto o = std::make_shared<ExportOptions>();
  CLI::App* cmd = app.add_subcommand("export", "Write a reconstruction (or a mesh + material) in standard formats");
  cmd->footer(
      "Reads RECON_DIR (an output folder of difftrans reconstruct): mesh_stage2.obj, else mesh_stage1.obj;\n"
      "material_stage2.json (+ its absorption grid); envmap_stage2.hdr, else envmap.hdr; the scene reconstruct.json records (cameras).\n"
      "--mesh, --material/--ior/--absorption, --env and --scene replace those (or export a ground truth alone).\n"
      "Writes into the folder --out:\n"
      "  gltf     object.glb: glTF 2.0 binary, KHR_materials_transmission / _ior / _volume (attenuation = sigma)\n"
      "  mitsuba  scene.xml (Mitsuba 3: dielectric, homogeneous interior medium, envmap, one perspective sensor\n"
      "           per camera of --split), mesh.ply (or --mesh-format obj) and the environment map beside it\n"
      "  ply, obj mesh.ply / mesh.obj and material.json (+ absorption_grid.json)\n"
      "gltf and mitsuba hold one absorption coefficient: a grid is averaged over the object's volume.\n"
      "Example: difftrans export out/recon --format gltf --out out/recon_gltf");
  cmd->add_option("RECON_DIR", o->recon, "output folder of difftrans reconstruct");
  cmd->add_option("--format", o->format, "gltf, mitsuba, ply or obj")
      ->required()
      ->check(CLI::IsMember({"gltf", "mitsuba", "ply", "obj"}));
  cmd->add_option("--out", o->out, "output folder")->required();
  cmd->add_option("--mesh", o->mesh, "mesh (.obj or .ply) instead of the reconstruction's");
  o->material.add(cmd);
  cmd->add_option("--env", o->env, "mitsuba: environment (.hdr/.exr map or constant:R,G,B) instead of RECON_DIR/envmap_stage2.hdr or envmap.hdr");
  cmd->add_option("--scene", o->scene, "mitsuba: scene directory whose cameras become sensors (default: the recorded one)");
  cmd->add_option("--split", o->split, "mitsuba: which cameras of the scene")
      ->capture_default_str()
      ->check(CLI::IsMember({"train", "test", "all"}));
  cmd->add_option("--max-depth", o->max_depth, "mitsuba: surface interactions per path (as difftrans render)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--spp", o->spp, "mitsuba: samples per pixel")->capture_default_str()->check(CLI::Range(1, 1 << 20));
  cmd->add_option("--mesh-format", o->mesh_format, "mitsuba: the mesh file beside scene.xml")
      ->capture_default_str()
      ->check(CLI::IsMember({"ply", "obj"}));
  cmd->add_flag("--overwrite", o->overwrite, "replace an existing, non-empty --out");
  cmd->callback([o] { run(*o); });
}

}  // namespace difftrans::cli
