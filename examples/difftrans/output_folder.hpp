// Output folders that are never seen half-written. A command writes into a
// work folder beside OUT and publishes it by replacing OUT in one step (an
// atomic exchange of the two folders), so that a process killed at any moment
// (SIGKILL, an out-of-memory kill, a lost session) leaves OUT as it was or as
// the last publication made it, never in between.
//
// OutputDir: commands that write their whole output at once (render, synth,
// relight, export, degrade) — OUT.partial replaces OUT at commit().
// RunFolder: `reconstruct`, which reads what earlier stages wrote and runs
// for hours — OUT.partial starts as a copy of OUT, and commit() publishes a
// copy of it after each stage and each checkpoint while the work goes on.
#pragma once

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>
#include <utility>
#include <vector>
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include "command.hpp"
#include "difftrans/io/error.hpp"

namespace difftrans::cli {

namespace detail {

inline std::filesystem::path sibling(const std::filesystem::path& folder, const char* suffix) {
  std::filesystem::path p = folder;
  p += suffix;
  return p;
}

// The name a folder has while `replace_folder` swaps it out without an atomic
// exchange (file systems that lack one): seen only when a process died between
// the two renames, and put back by `recover_folder`.
inline std::filesystem::path previous_name(const std::filesystem::path& folder) {
  return sibling(folder, ".previous");
}

// Puts back a folder that a process killed inside the fallback of
// replace_folder() left under its .previous name; removes a leftover one.
inline void recover_folder(const std::filesystem::path& folder) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path previous = previous_name(folder);
  if (!fs::exists(previous, ec)) return;
  if (!fs::exists(folder, ec)) {
    fs::rename(previous, folder, ec);
    if (ec) throw io::Error(folder, "cannot restore it from " + previous.string() + ": " + ec.message());
    warn(folder.string() + ": restored from " + previous.string() + ", where a killed run had left it");
  } else {
    fs::remove_all(previous, ec);
  }
}

// Makes `to` the folder `from` is, in one step where the system allows it:
// renameat2's exchange swaps the two names atomically, then the old contents
// (now under `from`) are removed. Without it (other kernels, some network file
// systems): `to` is renamed aside, `from` into place, the old one removed —
// a kill between the two renames is undone by recover_folder().
inline void replace_folder(const std::filesystem::path& from, const std::filesystem::path& to) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(to, ec)) {
    fs::rename(from, to, ec);
    if (ec) throw io::Error(to, "cannot move " + from.string() + " into place: " + ec.message());
    return;
  }
#if defined(__linux__) && defined(RENAME_EXCHANGE)
  if (renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_EXCHANGE) == 0) {
    fs::remove_all(from, ec);  // the old contents; a failure here leaves garbage, not damage
    return;
  }
  if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP)
    throw io::Error(to, "cannot exchange it with " + from.string() + ": " + std::strerror(errno));
#endif
  const fs::path previous = previous_name(to);
  fs::remove_all(previous, ec);
  fs::rename(to, previous, ec);
  if (ec) throw io::Error(to, "cannot move it aside to " + previous.string() + ": " + ec.message());
  fs::rename(from, to, ec);
  if (ec) {
    std::error_code back;
    fs::rename(previous, to, back);
    throw io::Error(to, "cannot move " + from.string() + " into place: " + ec.message());
  }
  fs::remove_all(previous, ec);
}

// A work folder beside OUT, created empty and locked (flock) while this
// process lives, so that a second command on the same OUT stops at once
// instead of deleting the first one's work. A work folder left by a killed
// process holds no lock and is cleared.
class WorkFolder {
 public:
  WorkFolder(const std::filesystem::path& final_folder, const char* suffix) : path_(sibling(final_folder, suffix)) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::exists(path_, ec)) {
      const int fd = ::open(path_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
      if (fd >= 0) {
        const bool busy = ::flock(fd, LOCK_EX | LOCK_NB) != 0;
        ::close(fd);
        if (busy)
          throw io::Error(final_folder, "another difftrans command is writing into this folder (its work folder " +
                                            path_.string() + " is in use)");
      }
      fs::remove_all(path_, ec);
      if (ec) throw io::Error(path_, "cannot clear the work folder a killed run left: " + ec.message());
    }
    fs::create_directories(path_, ec);
    if (ec) throw io::Error(path_, "cannot create directory: " + ec.message());
    fd_ = ::open(path_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd_ < 0 || ::flock(fd_, LOCK_EX | LOCK_NB) != 0)
      throw io::Error(final_folder, "another difftrans command is writing into this folder (its work folder " +
                                        path_.string() + " is in use)");
  }
  ~WorkFolder() {
    if (fd_ >= 0) ::close(fd_);
  }
  WorkFolder(const WorkFolder&) = delete;
  WorkFolder& operator=(const WorkFolder&) = delete;

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

inline void check_folder_name(const std::filesystem::path& out) {
  namespace fs = std::filesystem;
  if (out.empty()) throw CLI::ValidationError("--out", "is empty");
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec)) throw io::Error(out, "exists and is not a directory");
}

}  // namespace detail

// An output folder written in full or not at all: everything goes to
// OUT.partial, which replaces OUT only at commit(). An existing, non-empty OUT
// is refused unless `overwrite`; on failure OUT is untouched.
class OutputDir {
 public:
  // `inputs`: files and folders the command reads, which must not lie inside
  // OUT (replacing OUT would delete them); the working directory neither.
  OutputDir(std::filesystem::path out, bool overwrite, const std::vector<std::filesystem::path>& inputs = {})
      : final_(checked(std::move(out), overwrite, inputs)), work_(final_, ".partial") {}
  ~OutputDir() {
    if (!committed_) {
      std::error_code ec;
      std::filesystem::remove_all(work_.path(), ec);
    }
  }
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;

  const std::filesystem::path& path() const { return work_.path(); }
  const std::filesystem::path& final_path() const { return final_; }

  void commit() {
    detail::replace_folder(work_.path(), final_);
    committed_ = true;
  }

 private:
  // OUT, once it is known that it may be replaced (before any work folder exists)
  static std::filesystem::path checked(std::filesystem::path out, bool overwrite,
                                       const std::vector<std::filesystem::path>& inputs) {
    namespace fs = std::filesystem;
    detail::check_folder_name(out);
    detail::recover_folder(out);
    std::error_code ec;
    if (fs::exists(out, ec)) {
      if (!fs::is_empty(out, ec) && !overwrite)
        throw io::Error(out, "exists and is not empty (pass --overwrite to replace it)");
      const fs::path root = fs::weakly_canonical(out, ec);
      std::vector<fs::path> guarded = inputs;
      guarded.push_back(fs::current_path(ec));
      for (const auto& in : guarded) {
        if (in.empty()) continue;
        const fs::path p = fs::weakly_canonical(in, ec);
        const auto rel = p.lexically_relative(root);
        if (!rel.empty() && *rel.begin() != "..")
          throw io::Error(out, "refusing to replace this folder: it contains " + in.string());
      }
    }
    return out;
  }

  std::filesystem::path final_;
  detail::WorkFolder work_;
  bool committed_ = false;
};

// The output folder of a long, resumable command. The work happens in
// OUT.partial, which starts as a copy of OUT (earlier stages' results and
// checkpoints); commit() publishes a copy of the work folder as OUT in one
// step and the work goes on. So OUT always holds a state the command meant
// to leave: as it was before the run, or as at its last commit. Paths of
// files in the work folder are shown (messages, records) by their names in
// OUT, where they will be read.
class RunFolder {
 public:
  explicit RunFolder(std::filesystem::path out)
      : final_((detail::check_folder_name(out), detail::recover_folder(out), std::move(out))), work_(final_, ".partial") {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::exists(final_, ec)) {
      fs::copy(final_, work_.path(), fs::copy_options::recursive | fs::copy_options::copy_symlinks, ec);
      if (ec) {
        const std::string why = ec.message();
        fs::remove_all(work_.path(), ec);
        throw io::Error(final_, "cannot copy it into the work folder " + work_.path().string() + ": " + why);
      }
    }
  }
  ~RunFolder() {
    std::error_code ec;
    std::filesystem::remove_all(work_.path(), ec);
  }
  RunFolder(const RunFolder&) = delete;
  RunFolder& operator=(const RunFolder&) = delete;

  // where to write
  const std::filesystem::path& work() const { return work_.path(); }
  // OUT
  const std::filesystem::path& path() const { return final_; }
  // a path inside the work folder by the name it has in OUT; others unchanged
  std::filesystem::path shown(const std::filesystem::path& file) const {
    const std::filesystem::path rel = file.lexically_relative(work_.path());
    if (rel.empty() || *rel.begin() == "..") return file;
    return final_ / rel;
  }

  // OUT becomes a copy of the work folder as it is now, in one step.
  void commit() {
    namespace fs = std::filesystem;
    std::error_code ec;
    const fs::path next = detail::sibling(final_, ".next");
    fs::remove_all(next, ec);
    fs::copy(work_.path(), next, fs::copy_options::recursive | fs::copy_options::copy_symlinks, ec);
    if (ec) {
      std::error_code ignored;
      fs::remove_all(next, ignored);
      throw io::Error(final_, "cannot copy the work folder " + work_.path().string() + " for publishing: " + ec.message());
    }
    detail::replace_folder(next, final_);
  }

 private:
  std::filesystem::path final_;
  detail::WorkFolder work_;
};

}  // namespace difftrans::cli
