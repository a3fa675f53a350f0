// JSON reading: syntax errors at line and column; typed fields named by path.
#include "difftrans/io/json.hpp"

#include <cstddef>
#include <string>
#include <utility>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("malformed JSON: the error names file, line and column") {
  TempDir dir;
  const auto path = dir / "t.json";
  write_text(path, "{\n  \"w\": 64,\n  \"h\": 64,,\n}\n");
  const auto msg = error_of([&] { io::read_json(path); });
  CHECK(contains(msg, path.string() + ":3: malformed JSON at column 11: syntax error"));
  write_text(path, "{\"frames\": [");
  CHECK(contains(error_of([&] { io::read_json(path); }), path.string() + ":1: malformed JSON at column 13"));
  write_text(path, "{\"a\": 1e999}");
  CHECK(contains(error_of([&] { io::read_json(path); }), path.string() + ": malformed JSON"));
  CHECK(error_of([&] { io::read_json(dir / "no.json"); }) == (dir / "no.json").string() + ": file not found");
}

TEST_CASE("typed fields: missing, wrong type, non-integer, matrices") {
  const io::Json j = io::Json::parse(R"({"w": 64.5, "name": 3, "ok": "yes", "m": [[1, 2], [3]], "frames": [{"x": "a"}]})");
  const io::JsonReader r(j, "f.json");
  CHECK(error_of([&] { r.number("h"); }) == "f.json: h: missing");
  CHECK(error_of([&] { r.integer("w"); }) == "f.json: w: expected an integer, found 64.5");
  CHECK(error_of([&] { r.string("name"); }) == "f.json: name: expected a string, found 3");
  CHECK(error_of([&] { r.boolean("ok", false); }) == "f.json: ok: expected true or false, found \"yes\"");
  CHECK(error_of([&] { r.matrix("m", 2, 2); }) == "f.json: m: expected 2 rows of 2 numbers");
  CHECK(error_of([&] { r.child("frames").element(0).number("x"); }) == "f.json: frames[0].x: expected a number, found \"a\"");
  CHECK(error_of([&] { r.child("frames").element(1); }) == "f.json: frames: has no element 1");
  CHECK(error_of([&] { r.child("w").element(0); }) == "f.json: w: expected an array, found number");
  CHECK(r.number("missing", 7.0) == 7.0);
  CHECK(r.number("w") == 64.5);
  const io::Json arr = io::Json::parse("[1]");
  CHECK(error_of([&] { io::JsonReader(arr, "a.json").number("x"); }) == "a.json: expected a JSON object, found array");
}

TEST_CASE("write_json then read_json") {
  TempDir dir;
  const io::Json j = {{"chamfer", 1.5e-4}, {"list", {1, 2, 3}}};
  io::write_json(dir / "o.json", j);
  CHECK(io::read_json(dir / "o.json") == j);
}

namespace {
// `depth` arrays nested in one another, the innermost holding 1.
std::string nested_arrays(std::size_t depth) { return std::string(depth, '[') + "1" + std::string(depth, ']'); }
}  // namespace

TEST_CASE("deep nesting: refused at its line and column, whatever the depth; the limit itself reads") {
  TempDir dir;
  const auto path = dir / "deep.json";
  write_text(path, nested_arrays(io::max_json_depth));
  CHECK_NOTHROW(io::read_json(path));
  for (const std::size_t depth : {std::size_t(io::max_json_depth) + 1, std::size_t(40000), std::size_t(80000)}) {
    write_text(path, "{\"frames\":\n  " + nested_arrays(depth) + "}");
    const std::string msg = error_of([&] { io::read_json(path); });
    // the object is level 1, so the array that breaks the limit is the 64th '[' on line 2, at column 3 + 63
    CHECK(msg == path.string() + ":2: malformed JSON at column 66: arrays and objects nested deeper than 64 levels "
                                 "(no difftrans file nests more than a few)");
  }
  // brackets inside strings do not count
  write_text(path, "{\"a\": \"" + std::string(1000, '[') + "\"}");
  CHECK(io::read_json(path)["a"].get<std::string>().size() == 1000);
}

TEST_CASE("messages quote a short excerpt of a value, never the whole of it") {
  // a value nested 40,000 deep and a 1 MB string: the messages stay short
  // (moved in: copying a value is recursive in the JSON library)
  io::Json deep = io::Json::parse(nested_arrays(40000));
  io::Json j = io::Json::object();
  j["deep"] = std::move(deep);
  j["long"] = std::string(1 << 20, 'x');
  j["list"] = io::Json::array();
  for (int i = 0; i < 100000; ++i) j["list"].push_back(i);
  const io::JsonReader r(j, "f.json");
  const std::string a = error_of([&] { r.number("deep"); });
  CHECK(a.rfind("f.json: deep: expected a number, found [[[[", 0) == 0);
  CHECK(a.size() < 200);
  CHECK(a.substr(a.size() - 3) == "...");
  const std::string b = error_of([&] { r.integer("list"); });
  CHECK(b.rfind("f.json: list: expected a number, found [0, 1, 2, 3,", 0) == 0);
  CHECK(b.size() < 200);
  const std::string c = error_of([&] { r.boolean("long", false); });
  CHECK(c.rfind("f.json: long: expected true or false, found \"xxxx", 0) == 0);
  CHECK(c.size() < 200);
  // short values are quoted whole
  CHECK(io::json_excerpt(io::Json::parse(R"({"a": [1, 2], "b": "c"})")) == R"({"a": [1, 2], "b": "c"})");
  CHECK(io::json_excerpt(io::Json::parse(nested_arrays(3))) == "[[[1]]]");
  // a cut never ends inside a UTF-8 sequence: '"' and four two-byte letters of the ten bytes
  std::string e_acute;
  for (int i = 0; i < 100; ++i) e_acute += "\xc3\xa9";
  CHECK(io::json_excerpt(io::Json(e_acute), 10) == "\"\xc3\xa9\xc3\xa9\xc3\xa9\xc3\xa9...");
}

TEST_CASE("a syntax error after a long token quotes a short part of it") {
  TempDir dir;
  const auto path = dir / "long.json";
  write_text(path, "{\"a\": \"" + std::string(100000, 'y'));  // an unterminated string
  const std::string msg = error_of([&] { io::read_json(path); });
  CHECK(contains(msg, path.string() + ":1: malformed JSON at column"));
  CHECK(msg.size() < 400);
}

TEST_CASE("numbers stored as float: beyond the float range is an error naming the field and the value") {
  const io::Json j = io::Json::parse(R"({"big": 1e39, "neg": -3.5e38, "ok": 3.4e38, "small": 1e-50})");
  const io::JsonReader r(j, "f.json");
  CHECK(error_of([&] { r.float_number("big"); }) ==
        "f.json: big: 1e+39 is beyond the range of a float (magnitude at most 3.4e38), the type that stores it");
  CHECK(contains(error_of([&] { r.float_number("neg"); }), "f.json: neg: -3.5e+38 is beyond the range of a float"));
  CHECK(r.float_number("ok") == doctest::Approx(3.4e38f));
  CHECK(r.float_number("small") == 0.0f);  // underflows to 0: harmless
  CHECK(r.float_number("missing", 2.0f) == 2.0f);
  CHECK(r.number("big") == 1e39);  // as a double it is fine
}
