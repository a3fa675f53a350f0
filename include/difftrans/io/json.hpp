// JSON files through nlohmann-json: reading with errors that name the file,
// line and column, typed field access whose errors name the field, writing.
#pragma once

#include <nlohmann/json.hpp>

#include <cmath>
#include <string>

#include "difftrans/io/error.hpp"

namespace difftrans::io {

using Json = nlohmann::json;

// Parses JSON text; a syntax error becomes an Error at its line and column.
inline Json parse_json(const std::string& text, const std::filesystem::path& file) {
  try {
    return Json::parse(text);
  } catch (const Json::parse_error& e) {
    const size_t byte = std::min<size_t>(e.byte > 0 ? e.byte - 1 : 0, text.size());
    long line = 1;
    size_t line_start = 0;
    for (size_t i = 0; i < byte; ++i)
      if (text[i] == '\n') {
        ++line;
        line_start = i + 1;
      }
    // nlohmann's message: "[json.exception.parse_error.101] parse error at line L, column C: WHAT"
    std::string what = e.what();
    const size_t colon = what.find(": ", what.find("parse error"));
    if (colon != std::string::npos) what = what.substr(colon + 2);
    throw Error(file, "malformed JSON at column " + std::to_string(byte - line_start + 1) + ": " + what, line);
  } catch (const Json::exception& e) {  // e.g. a number too large for a double
    throw Error(file, std::string("malformed JSON: ") + e.what());
  }
}

inline Json read_json(const std::filesystem::path& path) { return parse_json(detail::read_file_text(path), path); }

inline void write_json(const std::filesystem::path& path, const Json& json, int indent = 2) {
  const std::string text = json.dump(indent) + "\n";
  detail::write_file_bytes(path, text.data(), text.size());
}

// Typed access to a JSON object's fields; errors name the file and the field
// by its path in the document ("frames[3].transform_matrix").
class JsonReader {
 public:
  JsonReader(const Json& json, const std::filesystem::path& file, std::string where = "")
      : json_(json), file_(file), where_(std::move(where)) {}

  const Json& json() const { return json_; }
  const std::string& where() const { return where_; }
  bool has(const std::string& key) const { return json_.is_object() && json_.contains(key) && !json_[key].is_null(); }
  std::string field(const std::string& key) const { return where_.empty() ? key : where_ + "." + key; }

  [[noreturn]] void fail(const std::string& what) const {
    throw Error(file_, (where_.empty() ? std::string() : where_ + ": ") + what);
  }
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw Error(file_, field(key) + ": " + what);
  }

  void require_object() const {
    if (!json_.is_object()) fail("expected a JSON object, found " + std::string(json_.type_name()));
  }

  const Json& at(const std::string& key) const {
    require_object();
    if (!has(key)) fail(key, "missing");
    return json_[key];
  }
  JsonReader child(const std::string& key) const { return {at(key), file_, field(key)}; }
  JsonReader element(size_t i) const {
    if (!json_.is_array()) fail("expected an array, found " + std::string(json_.type_name()));
    if (i >= json_.size()) fail("has no element " + std::to_string(i));
    return {json_[i], file_, where_ + "[" + std::to_string(i) + "]"};
  }

  // A finite number.
  double number(const std::string& key) const { return as_number(at(key), field(key)); }
  double number(const std::string& key, double fallback) const { return has(key) ? number(key) : fallback; }
  // An integer (a number with no fractional part, within int range).
  int integer(const std::string& key) const {
    const double v = number(key);
    if (v != std::floor(v) || std::abs(v) > 2147483647.0) fail(key, "expected an integer, found " + at(key).dump());
    return int(v);
  }
  std::string string(const std::string& key) const {
    const Json& v = at(key);
    if (!v.is_string()) fail(key, "expected a string, found " + v.dump());
    return v.get<std::string>();
  }
  std::string string(const std::string& key, const std::string& fallback) const {
    return has(key) ? string(key) : fallback;
  }
  bool boolean(const std::string& key, bool fallback) const {
    if (!has(key)) return fallback;
    const Json& v = at(key);
    if (!v.is_boolean()) fail(key, "expected true or false, found " + v.dump());
    return v.get<bool>();
  }
  // An array of `rows` arrays of `cols` finite numbers, row-major.
  std::vector<double> matrix(const std::string& key, size_t rows, size_t cols) const {
    const Json& v = at(key);
    const auto bad = [&] {
      fail(key, "expected " + std::to_string(rows) + " rows of " + std::to_string(cols) + " numbers");
    };
    if (!v.is_array() || v.size() != rows) bad();
    std::vector<double> out;
    for (size_t r = 0; r < rows; ++r) {
      if (!v[r].is_array() || v[r].size() != cols) bad();
      for (size_t c = 0; c < cols; ++c)
        out.push_back(as_number(v[r][c], field(key) + "[" + std::to_string(r) + "][" + std::to_string(c) + "]"));
    }
    return out;
  }

 private:
  double as_number(const Json& v, const std::string& name) const {
    if (!v.is_number()) throw Error(file_, name + ": expected a number, found " + v.dump());
    const double x = v.get<double>();
    if (!std::isfinite(x)) throw Error(file_, name + ": not a finite number");
    return x;
  }

  const Json& json_;
  std::filesystem::path file_;
  std::string where_;
};

}  // namespace difftrans::io
