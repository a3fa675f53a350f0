// JSON reading: syntax errors at line and column; typed fields named by path.
#include "difftrans/io/json.hpp"

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
