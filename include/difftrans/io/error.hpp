// The exception every io function throws on bad input: its message names the
// file, the line where known, and what is wrong ("scene/a.json:12: ...").
#pragma once

#include <cctype>
#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>

namespace difftrans::io {

class Error : public std::runtime_error {
 public:
  // line = 0: no line (binary formats, whole-file problems).
  Error(const std::filesystem::path& file, const std::string& what, long line = 0)
      : std::runtime_error(format(file, what, line)), file_(file), line_(line), reason_(what) {}

  const std::filesystem::path& file() const noexcept { return file_; }
  long line() const noexcept { return line_; }
  // The message without the file and line prefix.
  const std::string& reason() const noexcept { return reason_; }

  static std::string format(const std::filesystem::path& file, const std::string& what, long line) {
    std::string s = file.string();
    if (line > 0) s += ":" + std::to_string(line);
    return s + ": " + what;
  }

 private:
  std::filesystem::path file_;
  long line_;
  std::string reason_;
};

namespace detail {

// Cuts `s` to at most `limit` bytes (not inside a UTF-8 sequence), marking the cut with "...".
inline std::string cut_text(std::string s, std::size_t limit) {
  if (s.size() <= limit) return s;
  std::size_t n = limit;
  while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0) == 0x80) --n;
  s.resize(n);
  return s + "...";
}

// Text from a file quoted in a message: between single quotes, cut to 80
// bytes ("...") so that a runaway token cannot make the message long.
inline std::string excerpt(const std::string& s) { return "'" + cut_text(s, 80) + "'"; }

// Reads a whole file into memory, or throws an Error that says why not.
inline std::string read_file_text(const std::filesystem::path& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) throw Error(path, "file not found");
  if (std::filesystem::is_directory(status)) throw Error(path, "is a directory, not a file");
  std::FILE* f = std::fopen(path.string().c_str(), "rb");
  if (!f) throw Error(path, "cannot open for reading");
  std::string text;
  char buffer[1 << 16];
  std::size_t n;
  while ((n = std::fread(buffer, 1, sizeof(buffer), f)) > 0) text.append(buffer, n);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) throw Error(path, "read error");
  return text;
}

// Throws unless the file exists and is a regular file (before handing the
// path to a library whose own error would not say which file).
inline void require_readable(const std::filesystem::path& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) throw Error(path, "file not found");
  if (std::filesystem::is_directory(status)) throw Error(path, "is a directory, not a file");
  std::FILE* f = std::fopen(path.string().c_str(), "rb");
  if (!f) throw Error(path, "cannot open for reading");
  std::fclose(f);
}

// Writes bytes to a file, or throws.
inline void write_file_bytes(const std::filesystem::path& path, const void* data, std::size_t size) {
  std::FILE* f = std::fopen(path.string().c_str(), "wb");
  if (!f) throw Error(path, "cannot open for writing");
  const bool ok = std::fwrite(data, 1, size, f) == size;
  const bool closed = std::fclose(f) == 0;
  if (!ok || !closed) throw Error(path, "write error");
}

// The lowercase extension with its dot (".obj"), or "".
inline std::string lower_extension(const std::filesystem::path& path) {
  std::string e = path.extension().string();
  for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

}  // namespace detail
}  // namespace difftrans::io
