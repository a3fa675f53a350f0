// Every loader against damaged copies of small valid files made here: RGBE,
// EXR, PNG, JPEG, OBJ, PLY (ASCII and binary), the JSON files (a scene's
// transforms, scene.json, material, absorption grid, radiance field) and
// COLMAP models (binary and text). Each file is cut at many lengths, has bits
// flipped and bytes overwritten at many places, its magic replaced, sizes it
// declares made huge, values nested deep or out of range. Every case must load
// or throw an io::Error whose message names the file and stays short, within
// a second and without the process's memory jumping; cases that cannot be
// valid (empty files, impossible sizes, out-of-range values) must be refused.
// The cases are generated in code and deterministic, so this runs in every
// build (the libFuzzer targets in tests/fuzz/ need clang).
#include <sys/resource.h>

#include <chrono>
#include <cstring>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "difftrans/io/colmap.hpp"
#include "difftrans/io/dataset.hpp"
#include "difftrans/io/image_file.hpp"
#include "difftrans/io/material.hpp"
#include "difftrans/io/mesh_file.hpp"
#include "difftrans/io/radiance_field.hpp"
#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

namespace {

std::string file_bytes(const fs::path& path) { return io::detail::read_file_text(path); }

// (removed first: rewriting a file in place makes some file systems flush it
// to disk on close, thousands of times here)
void put_bytes(const fs::path& path, const std::string& bytes) {
  fs::remove(path);
  io::detail::write_file_bytes(path, bytes.data(), bytes.size());
}

// A case: a label for messages, the bytes, and whether they must be refused.
struct Case {
  std::string label;
  std::string bytes;
  bool must_fail = false;
};

// A loader under test: the file it reads (its damaged copies are written
// there), the valid bytes, how to load it, and cases of its own.
struct Loader {
  std::string name;
  fs::path path;
  std::string valid;
  std::function<void()> load;
  bool magic = true;      // the format starts with a signature: replacing it must be refused
  bool siblings = false;  // read with other files of a model, whose errors may name this one by its file name
  bool empty_is_valid = false;  // an empty file is a valid one (OBJ: no statements)
  bool cuts_fail = false;       // every cut (but of trailing white space) must be refused
  std::vector<Case> special;
};

// A small deterministic generator (the same cases on every run and platform).
struct Lcg {
  std::uint64_t state;
  std::uint32_t next() {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return std::uint32_t(state >> 33);
  }
  std::size_t below(std::size_t n) { return n == 0 ? 0 : std::size_t(next()) % n; }
};

// The generic damage: the empty file, cuts, bit flips, overwritten bytes,
// a replaced signature, trailing garbage.
std::vector<Case> generic_cases(const Loader& l, std::uint64_t seed) {
  std::vector<Case> cases;
  const std::string& v = l.valid;
  const std::size_t n = v.size();
  cases.push_back({"empty file", "", !l.empty_is_valid});
  // cuts: every length of a small file, 400 spread over a larger one, and the last 16
  std::vector<std::size_t> cuts;
  if (n <= 600) {
    for (std::size_t k = 1; k < n; ++k) cuts.push_back(k);
  } else {
    for (std::size_t k = 1; k <= 400; ++k) cuts.push_back(k * n / 401);
    for (std::size_t k = 1; k <= 16; ++k) cuts.push_back(n - k);
  }
  for (const std::size_t k : cuts) {
    const bool blank_tail = v.find_first_not_of(" \t\r\n", k) == std::string::npos;
    cases.push_back({"cut to " + std::to_string(k) + " of " + std::to_string(n) + " bytes", v.substr(0, k),
                     l.cuts_fail && !blank_tail});
  }
  Lcg rng{seed};
  for (int i = 0; i < 300; ++i) {
    const std::size_t at = rng.below(n);
    const int bit = int(rng.below(8));
    std::string b = v;
    b[at] = char(static_cast<unsigned char>(b[at]) ^ (1u << bit));
    cases.push_back({"bit " + std::to_string(bit) + " of byte " + std::to_string(at) + " flipped", b});
  }
  const unsigned char values[] = {0x00, 0xFF, 0x80, 0x7F, '9', '-', '"', '[', '{', '\n'};
  for (int i = 0; i < 150; ++i) {
    const std::size_t at = rng.below(n);
    const unsigned char value = values[rng.below(sizeof values)];
    std::string b = v;
    b[at] = char(value);
    cases.push_back({"byte " + std::to_string(at) + " set to " + std::to_string(int(value)), b});
  }
  std::string junk = v;
  for (std::size_t k = 0; k < std::min<std::size_t>(4, n); ++k) junk[k] = "JUNK"[k];
  cases.push_back({"signature replaced", junk, l.magic});
  cases.push_back({"trailing garbage", v + std::string(64, '\xA5')});
  cases.push_back({"the file twice", v + v});
  return cases;
}

// `text` with the first `from` replaced by `to` (which must be there).
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  REQUIRE_MESSAGE(at != std::string::npos, "'" << from << "' not found");
  return text.replace(at, from.size(), to);
}

// A token of a megabyte: messages quoting it must cut it short.
const std::string long_token(1 << 20, 'x');

std::string nested(std::size_t depth) { return std::string(depth, '[') + "1" + std::string(depth, ']'); }

// JSON cases: a value nested deep in place of `value` (a literal in the valid
// text), and numbers out of range for it.
void add_json_cases(Loader& l, const std::string& value, bool number_in_float = true) {
  for (const std::size_t depth : {200, 40000, 80000})
    l.special.push_back({"nested " + std::to_string(depth) + " deep", replaced(l.valid, value, nested(depth)), true});
  l.special.push_back({"1e400 (beyond double)", replaced(l.valid, value, "1e400"), true});
  if (number_in_float) l.special.push_back({"1e39 (beyond float)", replaced(l.valid, value, "1e39"), true});
  l.special.push_back({"a long string", replaced(l.valid, value, "\"" + std::string(1 << 20, 'x') + "\""), true});
}

long peak_rss_kb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

// Runs every case of a loader; returns {loaded, refused}.
std::pair<int, int> run_cases(const Loader& l, const std::vector<Case>& cases) {
  int loaded = 0, refused = 0;
  const std::string file = l.path.string();
  for (const Case& c : cases) {
    put_bytes(l.path, c.bytes);
    const long rss_before = peak_rss_kb();
    const auto t0 = std::chrono::steady_clock::now();
    bool threw = false;
    try {
      l.load();
    } catch (const io::Error& e) {
      threw = true;
      const std::string what = e.what();
      // the file by its path (or, where another file of the same model reports it, by its name)
      CHECK_MESSAGE((contains(what, file) || (l.siblings && contains(what, l.path.filename().string()))),
                    l.name << ", " << c.label << ": the message does not name " << file << ": " << what.substr(0, 300));
      // the reason quotes excerpts only
      CHECK_MESSAGE(e.reason().size() <= 600, l.name << ", " << c.label << ": a message of " << what.size()
                                                     << " characters: " << what.substr(0, 300) << "...");
    } catch (const std::exception& e) {
      threw = true;
      FAIL_CHECK(l.name << ", " << c.label << ": not an io::Error naming the file: " << e.what());
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    CHECK_MESSAGE(seconds < 1.0, l.name << ", " << c.label << ": took " << seconds << " s");
    const long grown_mb = (peak_rss_kb() - rss_before) / 1024;
    CHECK_MESSAGE(grown_mb < 256, l.name << ", " << c.label << ": the peak memory grew by " << grown_mb << " MB");
    if (c.must_fail) CHECK_MESSAGE(threw, l.name << ", " << c.label << ": loaded, but it cannot be a valid file");
    (threw ? refused : loaded) += 1;
  }
  return {loaded, refused};
}

void run_loader(Loader& l, std::uint64_t seed) {
  // the valid file loads
  put_bytes(l.path, l.valid);
  REQUIRE_NOTHROW(l.load());
  std::vector<Case> cases = generic_cases(l, seed);
  cases.insert(cases.end(), l.special.begin(), l.special.end());
  const auto t0 = std::chrono::steady_clock::now();
  const auto [loaded, refused] = run_cases(l, cases);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  MESSAGE(l.name << ": " << cases.size() << " cases, " << loaded << " loaded, " << refused << " refused, "
                 << seconds << " s");
  CHECK(refused > 0);
  put_bytes(l.path, l.valid);  // for loaders that read other files beside it
}

// A 16 x 6 image with varied pixels (so that compressed formats hold runs and literals).
io::Image test_image(int w = 16, int h = 6) {
  io::Image img(w, h);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = float((i * 37) % 101) / 50.0f;
  return img;
}

}  // namespace

TEST_CASE("images: RGBE, EXR, PNG, JPEG") {
  TempDir dir;
  // RGBE, run-length encoded (width 16) and flat (width 4)
  for (const int w : {16, 4}) {
    Loader l;
    l.name = "RGBE " + std::to_string(w) + " wide";
    l.path = dir / ("map" + std::to_string(w) + ".hdr");
    io::write_hdr(l.path, test_image(w, 6));
    l.valid = file_bytes(l.path);
    l.cuts_fail = true;
    l.load = [p = l.path] { io::read_image(p); };
    l.special.push_back({"declares 8000 x 8000", replaced(l.valid, "-Y 6 +X " + std::to_string(w), "-Y 8000 +X 8000"), true});
    l.special.push_back({"declares 2^31 rows", replaced(l.valid, "-Y 6 +X", "-Y 2147483648 +X"), true});
    run_loader(l, 11 + std::uint64_t(w));
  }
  {
    Loader l;
    l.name = "EXR";
    l.cuts_fail = true;
    l.path = dir / "image.exr";
    io::write_exr(l.path, test_image());
    l.valid = file_bytes(l.path);
    l.load = [p = l.path] { io::read_image(p); };
    // the data window (xMin, yMin, xMax, yMax as int32 after its name and type): made huge
    const std::string window = std::string("dataWindow\0box2i\0", 17);
    const std::size_t at = l.valid.find(window);
    REQUIRE(at != std::string::npos);
    const std::size_t box = at + window.size() + 4;  // after the attribute's size
    for (const std::int32_t big : {8192, 40000, 100000, 1 << 30}) {
      std::string b = l.valid;
      std::memcpy(&b[box + 8], &big, 4);
      std::memcpy(&b[box + 12], &big, 4);
      l.special.push_back({"data window up to " + std::to_string(big), b, true});
    }
    run_loader(l, 21);
  }
  {
    Loader l;
    l.name = "PNG";
    l.cuts_fail = true;
    l.path = dir / "image.png";
    io::write_png(l.path, test_image());
    l.valid = file_bytes(l.path);
    l.load = [p = l.path] {
      io::read_image(p);
      io::read_mask(p);
      io::image_size(p);
    };
    // IHDR width and height (big-endian at bytes 16 and 20): made huge
    for (const std::uint32_t big : {16384u, 1u << 24, 0x7FFFFFFFu}) {
      std::string b = l.valid;
      for (int k = 0; k < 4; ++k) b[std::size_t(16 + k)] = b[std::size_t(20 + k)] = char((big >> (24 - 8 * k)) & 0xFF);
      l.special.push_back({"declares " + std::to_string(big) + " x " + std::to_string(big), b, true});
    }
    run_loader(l, 31);
  }
  {
    Loader l;
    l.name = "JPEG";
    l.cuts_fail = true;
    l.path = dir / "image.jpg";
    const io::Image img = test_image(32, 24);
    const std::vector<std::uint8_t> srgb = io::tone_map(img);
    REQUIRE(stbi_write_jpg(l.path.string().c_str(), img.width, img.height, 3, srgb.data(), 90));
    l.valid = file_bytes(l.path);
    l.load = [p = l.path] { io::read_image(p); };
    // the frame header (SOF0: FF C0, length, precision, height, width), made huge
    const std::size_t sof = l.valid.find("\xFF\xC0");
    REQUIRE(sof != std::string::npos);
    for (const int big : {16384, 65535}) {
      std::string b = l.valid;
      b[sof + 5] = b[sof + 7] = char(big >> 8);
      b[sof + 6] = b[sof + 8] = char(big & 0xFF);
      l.special.push_back({"declares " + std::to_string(big) + " x " + std::to_string(big), b, true});
    }
    run_loader(l, 41);
  }
}

TEST_CASE("meshes: OBJ, PLY") {
  TempDir dir;
  const io::Mesh cube = cube_mesh();
  {
    Loader l;
    l.name = "OBJ";
    l.path = dir / "mesh.obj";
    l.valid = "# a cube with quads, a polygon and relative indices\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
              "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nvt 0 0\nvn 0 0 1\nf 1 4 3 2\nf 5/1 6/1 7/1 8/1\n"
              "f 1//1 2//1 6//1 5//1\nf -5 -1 -2 -6\nf 1 5 8 4\nf 2 3 7 6\n";
    l.load = [p = l.path] { io::read_mesh(p); };
    l.magic = false;
    l.empty_is_valid = true;  // read as a mesh with no faces, and warned about
    std::string polygon = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf";
    for (int i = 0; i < 300; ++i) polygon += " " + std::to_string(1 + i % 3);
    l.special.push_back({"a face of 300 vertices", polygon + "\n", true});
    l.special.push_back({"a coordinate of 1e39", replaced(l.valid, "v 1 1 1", "v 1 1e39 1"), true});
    l.special.push_back({"a coordinate of a megabyte", replaced(l.valid, "v 1 1 1", "v 1 1 " + long_token), true});
    l.special.push_back({"a face index of a megabyte", replaced(l.valid, "f 1 5 8 4", "f 1 5 8 " + long_token), true});
    l.special.push_back({"an index beyond the vertices", replaced(l.valid, "f 1 5 8 4", "f 1 5 8 400000000000"), true});
    run_loader(l, 51);
  }
  for (const bool ascii : {false, true}) {
    Loader l;
    l.name = ascii ? "PLY ASCII" : "PLY binary";
    l.path = dir / (ascii ? "ascii.ply" : "binary.ply");
    if (ascii) {
      l.valid = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
                "3 0 1 2\n3 0 2 3\n";
      l.special.push_back({"a coordinate of 1e39", replaced(l.valid, "1 1 0\n", "1 1e39 0\n"), true});
      l.special.push_back({"a coordinate of a megabyte", replaced(l.valid, "1 1 0\n", "1 1 " + long_token + "\n"), true});
      l.special.push_back({"a header word of a megabyte", replaced(l.valid, "format ascii", "format " + long_token), true});
    } else {
      io::write_ply(l.path, cube);
      l.valid = file_bytes(l.path);
    }
    l.load = [p = l.path] { io::read_mesh(p); };
    l.cuts_fail = !ascii;
    l.special.push_back({"declares 4e9 vertices", replaced(l.valid, ascii ? "element vertex 4" : "element vertex 8",
                                                           "element vertex 4000000000"), true});
    l.special.push_back({"declares 2^63 faces", replaced(l.valid, ascii ? "element face 2" : "element face 12",
                                                         "element face 9223372036854775808"), true});
    run_loader(l, ascii ? 61 : 62);
  }
}

TEST_CASE("JSON files: transforms, scene.json, material, absorption grid, radiance field") {
  TempDir dir;
  {  // a scene: the transforms file damaged, loaded with pixels
    io::write_image(in_new_dir(dir / "scene/images/r_0.png"), test_image(8, 6));
    io::Mask mask(8, 6);
    mask.inside[20] = 1;
    io::write_mask(in_new_dir(dir / "scene/masks/r_0.png"), mask);
    Loader l;
    l.name = "transforms_train.json";
    l.cuts_fail = true;
    l.path = dir / "scene/transforms_train.json";
    l.valid = R"({"camera_angle_x": 0.8, "w": 8, "h": 6, "frames": [{"file_path": "images/r_0", )"
              R"("transform_matrix": [[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 3.25], [0, 0, 0, 1]]}]})";
    l.load = [d = dir / "scene"] { io::load_scene(d); };
    l.magic = true;  // "JUNK" is not JSON
    add_json_cases(l, "3.25");
    l.special.push_back({"a camera at 1e20", replaced(l.valid, "3.25", "1e20"), true});
    l.special.push_back({"w, h 4096 for 8 x 6 images", replaced(l.valid, R"("w": 8, "h": 6)", R"("w": 4096, "h": 4096)"), true});
    l.special.push_back({"w, h 100000", replaced(l.valid, R"("w": 8, "h": 6)", R"("w": 100000, "h": 100000)"), true});
    l.special.push_back({"a file_path of a megabyte", replaced(l.valid, "images/r_0", long_token), true});
    l.special.push_back({"frames nested deep", replaced(l.valid, R"("frames": [)", R"("frames": )" + nested(80000) + R"(, "x": [)"), true});
    run_loader(l, 71);
    // the same file, cameras only
    l.name = "transforms_train.json (cameras only)";
    l.load = [d = dir / "scene"] {
      io::LoadOptions cameras;
      cameras.read_pixels = false;
      io::load_scene(d, cameras);
    };
    run_loader(l, 72);
  }
  {
    Loader l;
    l.name = "scene.json";
    l.cuts_fail = true;
    l.path = dir / "settings/scene.json";
    fs::create_directories(l.path.parent_path());
    l.valid = R"({"aabb": [[-1, -1, -1], [1, 1, 2.5]], "environment": "distant"})";
    l.load = [p = l.path] { io::load_scene_settings(p); };
    add_json_cases(l, "2.5", false);
    run_loader(l, 81);
  }
  {
    Loader l;
    l.name = "material.json";
    l.cuts_fail = true;
    l.path = dir / "material.json";
    l.valid = R"({"ior": 1.45, "absorption": {"type": "homogeneous", "sigma": [4.0, 0.5, 4.0]}})";
    l.load = [p = l.path] { io::read_material(p); };
    add_json_cases(l, "0.5");
    l.special.push_back({"absorption 1e39 as an array", R"({"ior": 1.5, "absorption": [1, 1e39, 1]})", true});
    l.special.push_back({"an unknown absorption type", replaced(l.valid, "homogeneous", "mystery"), true});
    l.special.push_back({"an absorption type of a megabyte", replaced(l.valid, "homogeneous", long_token), true});
    run_loader(l, 91);
  }
  {
    Loader l;
    l.name = "absorption grid";
    l.cuts_fail = true;
    l.path = dir / "grid.json";
    io::write_absorption_grid(l.path, io::sample_absorption_grid(difftrans::Vec3i(2, 2, 3), difftrans::Vec3f(-1.0f),
                                                                 difftrans::Vec3f(1.0f), [](const difftrans::Vec3f& p) {
                                                                   return difftrans::Vec3f(0.25f, p.y + 1.5f, 2.0f);
                                                                 }));
    l.valid = file_bytes(l.path);
    l.load = [p = l.path] { io::read_absorption_grid(p); };
    add_json_cases(l, "0.25");
    l.special.push_back({"declares 4096^3", replaced(l.valid, "[2,2,3]", "[4096,4096,4096]"), true});
    run_loader(l, 101);
  }
  {
    Loader l;
    l.name = "radiance field";
    l.cuts_fail = true;
    l.path = dir / "field/radiance_field.json";
    fs::create_directories(l.path.parent_path());
    difftrans::scene::RadianceField f(difftrans::Vec3i(2, 3, 2), difftrans::Vec3f(-1.0f), difftrans::Vec3f(1.0f),
                                      -2.0f, 0.5f);
    f.density_scale = 2.5f;
    io::write_radiance_field(l.path, f, 0.0f);
    l.valid = file_bytes(l.path);
    l.load = [p = l.path] { io::read_radiance_field(p); };
    add_json_cases(l, "2.5");
    l.special.push_back({"declares 4096^3", replaced(l.valid, "[\n    2,\n    3,\n    2\n  ]", "[4096, 4096, 4096]"), true});
    run_loader(l, 111);
  }
}

TEST_CASE("COLMAP models: binary and text") {
  TempDir dir;
  io::write_image(in_new_dir(dir / "images/a.png"), test_image(8, 6));
  io::write_image(in_new_dir(dir / "images/b.png"), test_image(8, 6));
  io::Split split;
  for (const char* name : {"a.png", "b.png"}) {
    io::Frame f;
    f.image_path = dir / "images" / name;
    f.intrinsics = io::Intrinsics::from_fov_x(8, 6, 0.9);
    f.camera_to_world[3] = glm::dvec4(0.5, -0.25, 3.0, 1.0);
    split.frames.push_back(f);
  }
  io::write_colmap_binary(dir / "model", split, dir / "images");
  const auto load = [&] { io::load_colmap(dir / "model", dir / "images"); };
  for (const char* name : {"cameras.bin", "images.bin"}) {
    Loader l;
    l.name = name;
    l.path = dir / "model" / name;
    l.valid = file_bytes(l.path);
    l.load = load;
    l.magic = false;  // a count comes first
    l.cuts_fail = true;
    l.siblings = true;
    // the first count (u64) made huge
    std::string b = l.valid;
    for (int k = 0; k < 8; ++k) b[std::size_t(k)] = char(k == 7 ? 0x7F : 0xFF);
    l.special.push_back({"declares 2^63 records", b, true});
    run_loader(l, std::uint64_t(name[0]));
  }
  // text: the same model
  write_text(dir / "text/cameras.txt", "# id model w h params\n1 PINHOLE 8 6 10 10 4 3\n");
  write_text(dir / "text/images.txt", "# id qw qx qy qz tx ty tz camera name\n1 1 0 0 0 0.5 -0.25 3 1 a.png\n\n"
                                      "2 1 0 0 0 0 0 3 1 b.png\n\n");
  for (const char* name : {"cameras.txt", "images.txt"}) {
    Loader l;
    l.name = name;
    l.path = dir / "text" / name;
    l.valid = file_bytes(l.path);
    l.load = [&] { io::load_colmap(dir / "text", dir / "images"); };
    l.magic = false;
    l.siblings = true;
    if (std::string(name) == "images.txt") {
      l.special.push_back({"a camera at 1e20", replaced(l.valid, "0.5 -0.25 3", "0.5 -0.25 1e20"), true});
      l.special.push_back({"a coordinate of a megabyte", replaced(l.valid, "0.5 -0.25 3", "0.5 -0.25 " + long_token), true});
    } else {
      l.special.push_back({"a model name of a megabyte", replaced(l.valid, "PINHOLE", long_token), true});
      l.special.push_back({"declares 100000 x 100000", replaced(l.valid, "PINHOLE 8 6", "PINHOLE 100000 100000"), true});
      l.special.push_back({"declares 4096 x 4096 for 8 x 6 images", replaced(l.valid, "PINHOLE 8 6", "PINHOLE 4096 4096"), true});
    }
    run_loader(l, std::uint64_t(name[0]) + 7);
  }
}
