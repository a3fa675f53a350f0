// difftrans synth: renders a synthetic scene directory (docs/scene-format.md) with its
// ground truth in gt/ — from a benchmark preset and variant, or from explicit
// options (each explicit option also overrides the preset's value).
#include "output_folder.hpp"
#include "views.hpp"

namespace difftrans::cli {
namespace {

struct SynthOptions {
  std::string preset, variant = "full";
  std::string mesh, env, absorption, absorption_grid, data;
  bool bands = false;
  std::optional<double> ior;
  std::optional<int> views, test_views, resolution, max_depth, spp_axis;
  std::string sphere;  // "", "sphere" or "hemisphere"
  std::uint64_t seed = 0;
  std::string out;
  bool overwrite = false;
  bool room = false;        // the object inside a textured box room (a near-field environment)
  double room_size = 8.0;   // the room's edge length, centred on the object
};

// Everything a synthetic scene is made of, after presets and overrides.
struct SynthSpec {
  std::string id = "custom";
  fs::path mesh;
  io::Material material;
  std::string env_spec;
  io::ViewSphere sphere = io::ViewSphere::sphere;
  int resolution = 256, train_views = 100, test_views = 20, max_depth = 16, spp_axis = 4;
  std::uint64_t seed = 0;
  std::string variant;
  bool room = false;
  double room_size = 8.0;
};

SynthSpec resolve(const SynthOptions& o) {
  SynthSpec s;
  const fs::path data = data_dir(o.data);
  if (!o.preset.empty()) {
    const io::Preset& p = io::find_preset(o.preset);
    const io::Variant v = io::find_variant(o.variant);
    s.id = p.id;
    s.variant = v.name;
    s.mesh = data / "meshes" / p.mesh;
    s.material = io::preset_material(p);
    s.env_spec = (data / "envmaps" / p.environment).string();
    s.sphere = p.views;
    s.resolution = v.resolution;
    s.train_views = v.train_views;
    s.test_views = v.test_views;
    s.max_depth = v.max_depth;
    s.spp_axis = v.samples_per_axis;
  } else {
    if (o.mesh.empty() || !o.ior || (o.env.empty() && !o.room))
      throw CLI::ValidationError("without --preset, give --mesh, --ior and --env (or --room)");
    const io::Variant v = io::find_variant(o.variant);
    s.variant = v.name;
    s.resolution = v.resolution;
    s.train_views = v.train_views;
    s.test_views = v.test_views;
  }
  if (!o.mesh.empty()) s.mesh = o.mesh;
  if (o.ior) s.material.ior = *o.ior;
  if (int(!o.absorption.empty()) + int(o.bands) + int(!o.absorption_grid.empty()) > 1)
    throw CLI::ValidationError("--absorption, --absorption-bands and --absorption-grid exclude each other");
  if (!o.absorption.empty()) {
    const Vec3f sigma = parse_rgb(o.absorption, "--absorption");
    s.material.absorption = sigma == Vec3f(0.0f) ? io::AbsorptionType::none : io::AbsorptionType::homogeneous;
    s.material.sigma = sigma;
  }
  if (o.bands) {
    io::Preset bands;
    bands.ior = s.material.ior;
    bands.absorption = io::AbsorptionModel::bands;
    s.material = io::preset_material(bands);
  }
  if (!o.absorption_grid.empty()) {
    s.material.absorption = io::AbsorptionType::grid;
    s.material.grid = io::read_absorption_grid(o.absorption_grid);
    s.material.grid_file = "absorption_grid.json";
    s.material.procedural = "from " + o.absorption_grid;
  }
  if (!o.env.empty()) s.env_spec = o.env;
  if (o.sphere == "sphere") s.sphere = io::ViewSphere::sphere;
  if (o.sphere == "hemisphere") s.sphere = io::ViewSphere::upper_hemisphere;
  if (o.views) s.train_views = *o.views;
  if (o.test_views) s.test_views = *o.test_views;
  if (o.resolution) s.resolution = *o.resolution;
  if (o.max_depth) s.max_depth = *o.max_depth;
  if (o.spp_axis) s.spp_axis = *o.spp_axis;
  s.seed = o.seed;
  s.room = o.room;
  s.room_size = o.room_size;
  if (s.room && !o.env.empty()) throw CLI::ValidationError("--room and --env exclude each other");
  if (s.room && !(o.room_size > 2.0 * double(scene::protocol_camera_radius)))
    throw CLI::ValidationError("--room-size", "must exceed " + std::to_string(2.0 * scene::protocol_camera_radius) +
                                                  " so that the cameras (radius " +
                                                  std::to_string(scene::protocol_camera_radius) + ") lie inside the room");
  return s;
}

// The room seen from its centre (the object's), as an equirectangular map
// (docs/conventions.md), 4 × 4 samples per texel.
io::Image room_panorama(const scene::Room& room, int width = 512) {
  const int height = width / 2, n = 4;
  io::Image im(width, height);
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) {
      Vec3f sum(0.0f);
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const float u = (float(c) + (float(i) + 0.5f) / n) / float(width);
          const float v = (float(r) + (float(j) + 0.5f) / n) / float(height);
          sum += room.radiance(room.centre, scene::uv_to_direction(u, v));
        }
      im.set(c, r, sum / float(n * n));
    }
  return im;
}

io::Json describe_room(const scene::Room& room) {
  return io::Json{{"type", "box room"},
                  {"centre", {room.centre.x, room.centre.y, room.centre.z}},
                  {"half_size", room.half},
                  {"panel_radiance", {room.panel_radiance.x, room.panel_radiance.y, room.panel_radiance.z}},
                  {"ceiling_radiance", {room.ceiling_radiance.x, room.ceiling_radiance.y, room.ceiling_radiance.z}},
                  {"walls", "see include/difftrans/scene/room.hpp"}};
}

io::Json describe(const SynthSpec& s, const Environment& env) {
  io::Json j = io::Json::object();
  j["preset"] = s.id;
  j["variant"] = s.variant;
  j["source_mesh"] = s.mesh.string();
  if (s.room) {
    j["environment"] = "room";
    j["room_size"] = s.room_size;
  } else {
    j["environment"] = env.file.empty() ? env.spec : env.file.filename().string();
    j["environment_source"] = env.spec;
  }
  j["ior"] = s.material.ior;
  j["absorption"] = io::to_string(s.material.absorption);
  j["views"] = {{"train", s.train_views}, {"test", s.test_views}, {"placement", io::to_string(s.sphere)},
                {"radius", scene::protocol_camera_radius}, {"fov_y_degrees", 40.0}};
  j["resolution"] = s.resolution;
  j["samples_per_pixel"] = s.spp_axis * s.spp_axis;
  j["max_depth"] = s.max_depth;
  j["pruning"] = "none";
  j["absorption_integration"] = "exact";
  j["seed"] = s.seed;
  j["images"] = std::string("linear ") + linear_extension + " in images/, tone-mapped PNG in previews/";
  return j;
}

void run(const SynthOptions& o) {
  const SynthSpec s = resolve(o);
  progress("synth: " + s.id + (s.variant.empty() ? "" : " (" + s.variant + ")") + ": " + std::to_string(s.train_views) +
           " + " + std::to_string(s.test_views) + " views of " + std::to_string(s.resolution) + " x " +
           std::to_string(s.resolution) + ", " + std::to_string(s.spp_axis * s.spp_axis) + " samples per pixel, depth " +
           std::to_string(s.max_depth));
  // read every input before anything is written
  io::Mesh mesh = load_mesh(s.mesh);
  io::normalize_to_unit_box(mesh);
  const Environment env = s.room ? Environment{} : load_environment(s.env_spec);
  if (env.field) environment_image(env);  // refuses a radiance field before anything is written
  scene::Room room;
  room.half = float(s.room_size / 2.0);

  OutputDir out(o.out, o.overwrite, {s.mesh, env.file, o.absorption_grid});
  const fs::path dir = out.path();
  fs::create_directories(dir / "gt");
  io::write_mesh(dir / "gt" / "mesh.obj", mesh);
  io::write_material(dir / "gt" / "material.json", s.material);
  if (s.room)
    io::write_image(dir / "gt" / "envmap.hdr", room_panorama(room));
  else if (!env.file.empty() && io::detail::lower_extension(env.file) == ".hdr")
    fs::copy_file(env.file, dir / "gt" / "envmap.hdr");
  else
    io::write_image(dir / "gt" / "envmap.hdr", environment_image(env));
  io::write_json(dir / "gt" / "synth.json", describe(s, env));
  if (s.room) io::write_json(dir / "gt" / "room.json", describe_room(room));

  render::HostScene scene = render::make_host_scene(mesh, s.material, s.mesh.filename().string());
  if (!s.room) apply_environment(scene, env);
  const scene::Room* room_env = s.room ? &room : nullptr;
  const render::PassOptions options = render::reference_pass_options(s.max_depth, s.spp_axis);

  const io::ViewOffsets offsets = io::view_offsets(s.seed);
  const auto make_views = [&](const char* prefix, int n, double offset) {
    std::vector<View> views;
    const auto dirs = io::fibonacci_directions(n, s.sphere, offset);
    for (int i = 0; i < n; ++i) {
      char name[64];
      std::snprintf(name, sizeof(name), "%s_%03d", prefix, i);
      views.push_back(protocol_view(name, dirs[size_t(i)], s.resolution, s.resolution));
    }
    return views;
  };
  const auto train = render_views(scene, make_views("train", s.train_views, offsets.train), options, dir, true, "synth train", room_env);
  io::write_transforms(dir / "transforms_train.json", split_of(train));
  if (s.test_views > 0) {
    const auto test = render_views(scene, make_views("test", s.test_views, offsets.test), options, dir, true, "synth test", room_env);
    io::write_transforms(dir / "transforms_test.json", split_of(test));
  }
  io::SceneSettings settings;
  io::Box box = io::bounding_box(mesh);
  const double margin = 0.05 * std::max(box.size().x, std::max(box.size().y, box.size().z));
  box.lo -= Vec3d(margin);
  box.hi += Vec3d(margin);
  settings.aabb = box;
  settings.environment = s.room ? io::EnvironmentKind::near : io::EnvironmentKind::distant;
  io::write_scene_settings(dir / "scene.json", settings);
  out.commit();
  progress("synth: wrote " + out.final_path().string());
}

}  // namespace

void add_synth(CLI::App& app) {
  auto o = std::make_shared<SynthOptions>();
  CLI::App* cmd = app.add_subcommand("synth", "Render a synthetic scene directory with its ground truth in gt/");
  cmd->footer(
      "Presets (docs/benchmark-scenes.md): spot-clear, bunny-clear, horse-green, monkey-bands; variants full (256^2, 100 + 20\n"
      "views), quick (128^2, 50 + 20), test (64^2, 24 + 8). Explicit options override a preset's values.\n"
      "Cameras: Fibonacci points on the sphere or the upper hemisphere (y > 0.05), radius 3, looking at the origin,\n"
      "vertical FoV 40 degrees; test views use the same lattice turned by half a turn. Pixels: box filter over\n"
      "spp-axis^2 stratified samples; masks: the ray through the pixel centre hits the object.\n"
      "Writes images/NAME.exr (linear), previews/NAME.png, masks/NAME.png, transforms_train.json,\n"
      "transforms_test.json, scene.json and gt/ (mesh.obj normalized, material.json, envmap.hdr, synth.json).\n"
      "--room: the object inside a textured box room (--room-size across, centred on it; walls with\n"
      "different checker and stripe patterns, two emissive panels) instead of a distant map; scene.json says\n"
      "\"environment\": \"near\", gt/envmap.hdr is the room seen from the object's centre, gt/room.json the room.\n"
      "Example: difftrans synth --preset horse-green --variant quick --out scenes/horse-green-quick");
  cmd->add_option("--preset", o->preset, "benchmark scene")
      ->check(CLI::IsMember({"spot-clear", "bunny-clear", "horse-green", "monkey-bands"}));
  cmd->add_option("--variant", o->variant, "full, quick or test")->capture_default_str()
      ->check(CLI::IsMember({"full", "quick", "test"}));
  cmd->add_option("--out", o->out, "scene directory to write")->required();
  cmd->add_flag("--overwrite", o->overwrite, "replace an existing, non-empty --out");
  cmd->add_option("--mesh", o->mesh, "mesh (.obj or .ply); normalized to the unit box");
  cmd->add_option("--ior", o->ior, "index of refraction")->check(CLI::Range(1.0, 4.0));
  cmd->add_option("--absorption", o->absorption, "homogeneous absorption sigma_a R,G,B (0,0,0: clear)");
  cmd->add_flag("--absorption-bands", o->bands, "the procedural bands of monkey-bands (smooth step across y = 0)");
  cmd->add_option("--absorption-grid", o->absorption_grid, "absorption grid file");
  cmd->add_option("--env", o->env, "environment: equirectangular map (.hdr/.exr) or constant:R,G,B");
  cmd->add_option("--views", o->views, "training views")->check(CLI::Range(1, 100000));
  cmd->add_option("--test-views", o->test_views, "held-out test views")->check(CLI::Range(0, 100000));
  cmd->add_option("--placement", o->sphere, "cameras on the sphere or the upper hemisphere")
      ->check(CLI::IsMember({"sphere", "hemisphere"}));
  cmd->add_option("--resolution", o->resolution, "image width and height in pixels")->check(CLI::Range(1, 16384));
  cmd->add_option("--seed", o->seed, "turns the camera lattices (0: the protocol's)")->capture_default_str();
  cmd->add_option("--max-depth", o->max_depth, "surface interactions per path (reference: 16)")
      ->check(CLI::Range(1, render::max_trace_depth));
  cmd->add_option("--spp-axis", o->spp_axis, "n: n x n stratified samples per pixel (reference: 4)")->check(CLI::Range(1, 64));
  cmd->add_flag("--room", o->room, "place the object in a textured box room (near-field environment) instead of --env");
  cmd->add_option("--room-size", o->room_size, "edge length of the room (--room)")->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  cmd->add_option("--data", o->data,
                  "data folder with meshes/ and envmaps/ (default: $DIFFTRANS_DATA, else the data/ folder of the "
                  "difftrans sources or installation)");
  cmd->callback([o] { run(*o); });
}

}  // namespace difftrans::cli
