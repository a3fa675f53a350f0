// Binary checkpoints of long fits: an 8-byte tag, then scalars and arrays in
// the order the writer put them. The file is written beside its destination
// and renamed over it, so an interruption at any moment leaves the previous
// checkpoint or the new one, never a part of one; reading checks every count
// against the bytes left in the file before it allocates.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "difftrans/io/error.hpp"

namespace difftrans::io {

class CheckpointWriter {
 public:
  // `tag`: 8 characters naming the kind and version of the checkpoint.
  CheckpointWriter(std::filesystem::path path, const char (&tag)[9])
      : path_(std::move(path)), tmp_(path_.string() + ".tmp"), file_(tmp_, std::ios::binary | std::ios::trunc) {
    if (!file_) throw Error(tmp_, "cannot open the checkpoint for writing");
    file_.write(tag, 8);
  }

  template <class T>
  void value(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>, "checkpoint values are plain bytes");
    file_.write(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  template <class T>
  void array(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>, "checkpoint arrays hold plain bytes");
    value(std::uint64_t(v.size()));
    if (!v.empty()) file_.write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * sizeof(T)));
  }
  void text(const std::string& s) { array(std::vector<char>(s.begin(), s.end())); }

  // Closes the file and moves it over the destination; Error on failure (the
  // destination is then untouched).
  void commit() {
    file_.flush();
    const bool ok = bool(file_);
    file_.close();
    if (!ok || file_.fail()) throw Error(tmp_, "writing the checkpoint failed (disk full?)");
    std::error_code ec;
    std::filesystem::rename(tmp_, path_, ec);
    if (ec) throw Error(path_, "cannot move the new checkpoint into place: " + ec.message());
  }

 private:
  std::filesystem::path path_, tmp_;
  std::ofstream file_;
};

class CheckpointReader {
 public:
  // ok() is false when the file is absent or does not start with `tag`.
  CheckpointReader(const std::filesystem::path& path, const char (&tag)[9]) : file_(path, std::ios::binary) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    left_ = ec ? 0 : std::uint64_t(size);
    char head[8];
    ok_ = file_ && take(8) && file_.read(head, 8) && std::memcmp(head, tag, 8) == 0;
  }

  // False once anything failed: the file ended early, or a count was larger
  // than the file or than `max_count`. Reads after a failure do nothing.
  bool ok() const { return ok_; }

  template <class T>
  bool value(T& v) {
    static_assert(std::is_trivially_copyable_v<T>, "checkpoint values are plain bytes");
    ok_ = ok_ && take(sizeof(T)) && file_.read(reinterpret_cast<char*>(&v), sizeof(T));
    return ok_;
  }
  template <class T>
  bool array(std::vector<T>& v, std::uint64_t max_count) {
    std::uint64_t n = 0;
    if (!value(n) || n > max_count || n > left_ / sizeof(T)) return ok_ = false;
    v.resize(std::size_t(n));
    ok_ = n == 0 || (take(n * sizeof(T)) && file_.read(reinterpret_cast<char*>(v.data()), std::streamsize(n * sizeof(T))));
    return ok_;
  }
  bool text(std::string& s, std::uint64_t max_length) {
    std::vector<char> c;
    if (!array(c, max_length)) return false;
    s.assign(c.begin(), c.end());
    return true;
  }
  // True when everything was read and nothing is left over.
  bool complete() const { return ok_ && left_ == 0; }

 private:
  bool take(std::uint64_t bytes) {
    if (bytes > left_) return false;
    left_ -= bytes;
    return true;
  }

  std::ifstream file_;
  std::uint64_t left_ = 0;
  bool ok_ = false;
};

}  // namespace difftrans::io
