// JSON files through nlohmann-json: reading with errors that name the file,
// line and column (nesting depth bounded), typed field access whose errors
// name the field and quote a short excerpt of the value, writing.
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "difftrans/io/error.hpp"

namespace difftrans::io {

using Json = nlohmann::json;

// Deepest nesting of arrays and objects read from a file. No difftrans file
// nests deeper than 4; the bound is checked on the text before parsing, so a
// runaway file fails with a message instead of exhausting the stack in the
// JSON library's recursive functions (copying, printing a value).
inline constexpr int max_json_depth = 64;

// Longest excerpt of a value (or of the parser's last token) quoted in messages.
inline constexpr std::size_t json_excerpt_chars = 80;

namespace detail {

// Line (from 1) and column (from 1) of byte `byte` of `text`.
inline std::pair<long, std::size_t> line_and_column(const std::string& text, std::size_t byte) {
  byte = std::min(byte, text.size());
  long line = 1;
  std::size_t line_start = 0;
  for (std::size_t i = 0; i < byte; ++i)
    if (text[i] == '\n') {
      ++line;
      line_start = i + 1;
    }
  return {line, byte - line_start + 1};
}

// Byte offset of the first '[' or '{' nested deeper than `limit` outside
// strings, or npos. Brackets that do not match are left to the parser.
inline std::size_t json_too_deep(const std::string& text, int limit) {
  int depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') ++i;
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > limit) return i;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return std::string::npos;
}

// Appends the compact text of `v` to `out` until `out` exceeds `limit`
// characters: the work is bounded by the limit (and the recursion by
// max_json_depth), whatever the size of the value.
inline void append_excerpt(std::string& out, const Json& v, std::size_t limit, int depth) {
  if (out.size() > limit) return;
  const auto string_text = [&](const std::string& s) {
    // a cut string may end inside a UTF-8 sequence: replace what is invalid
    out += Json(s.substr(0, limit + 1)).dump(-1, ' ', false, Json::error_handler_t::replace);
  };
  if (v.is_array() || v.is_object()) {
    const bool array = v.is_array();
    if (depth >= max_json_depth) {
      out += array ? "[...]" : "{...}";
      return;
    }
    out += array ? '[' : '{';
    bool first = true;
    for (auto it = v.begin(); it != v.end() && out.size() <= limit; ++it) {
      if (!first) out += ", ";
      first = false;
      if (!array) {
        string_text(it.key());
        out += ": ";
      }
      append_excerpt(out, it.value(), limit, depth + 1);
    }
    out += array ? ']' : '}';
  } else if (v.is_string()) {
    string_text(v.get_ref<const std::string&>());
  } else {
    out += v.dump();
  }
}

}  // namespace detail

// A value as messages quote it: its compact JSON text, cut to `limit`
// characters with "..." when longer. Never prints more than the excerpt,
// however large or deeply nested the value.
inline std::string json_excerpt(const Json& v, std::size_t limit = json_excerpt_chars) {
  std::string out;
  detail::append_excerpt(out, v, limit, 0);
  return detail::cut_text(std::move(out), limit);
}

// Parses JSON text; a syntax error becomes an Error at its line and column,
// and so does nesting deeper than max_json_depth.
inline Json parse_json(const std::string& text, const std::filesystem::path& file) {
  const std::size_t deep = detail::json_too_deep(text, max_json_depth);
  if (deep != std::string::npos) {
    const auto [line, column] = detail::line_and_column(text, deep);
    throw Error(file, "malformed JSON at column " + std::to_string(column) + ": arrays and objects nested deeper than " +
                          std::to_string(max_json_depth) + " levels (no difftrans file nests more than a few)",
                line);
  }
  try {
    return Json::parse(text);
  } catch (const Json::parse_error& e) {
    const auto [line, column] = detail::line_and_column(text, e.byte > 0 ? e.byte - 1 : 0);
    // nlohmann's message: "[json.exception.parse_error.101] parse error at line L, column C: WHAT";
    // WHAT quotes the last token read, which may be a whole long string
    std::string what = e.what();
    const std::size_t colon = what.find(": ", what.find("parse error"));
    if (colon != std::string::npos) what = what.substr(colon + 2);
    throw Error(file, "malformed JSON at column " + std::to_string(column) + ": " +
                          detail::cut_text(what, 2 * json_excerpt_chars), line);
  } catch (const Json::exception& e) {  // e.g. a number too large for a double
    throw Error(file, "malformed JSON: " + detail::cut_text(e.what(), 2 * json_excerpt_chars));
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
  // A finite number that a float holds (|x| <= FLT_MAX), for values stored as float:
  // a larger double would become infinity there.
  float float_number(const std::string& key) const { return as_float(at(key), field(key)); }
  float float_number(const std::string& key, float fallback) const { return has(key) ? float_number(key) : fallback; }
  // `v` (which messages call `name`: a field, or an element of one) as a float, checked as float_number does.
  float as_float(const Json& v, const std::string& name) const {
    const double x = as_number(v, name);
    if (std::abs(x) > double(std::numeric_limits<float>::max()))
      throw Error(file_, name + ": " + json_excerpt(v) +
                             " is beyond the range of a float (magnitude at most 3.4e38), the type that stores it");
    return float(x);
  }
  // An integer (a number with no fractional part, within int range).
  int integer(const std::string& key) const {
    const double v = number(key);
    if (v != std::floor(v) || std::abs(v) > 2147483647.0) fail(key, "expected an integer, found " + json_excerpt(at(key)));
    return int(v);
  }
  std::string string(const std::string& key) const {
    const Json& v = at(key);
    if (!v.is_string()) fail(key, "expected a string, found " + json_excerpt(v));
    return v.get<std::string>();
  }
  std::string string(const std::string& key, const std::string& fallback) const {
    return has(key) ? string(key) : fallback;
  }
  bool boolean(const std::string& key, bool fallback) const {
    if (!has(key)) return fallback;
    const Json& v = at(key);
    if (!v.is_boolean()) fail(key, "expected true or false, found " + json_excerpt(v));
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
    if (!v.is_number()) throw Error(file_, name + ": expected a number, found " + json_excerpt(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) throw Error(file_, name + ": not a finite number");
    return x;
  }

  const Json& json_;
  std::filesystem::path file_;
  std::string where_;
};

}  // namespace difftrans::io
