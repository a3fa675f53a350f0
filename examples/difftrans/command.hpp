// Shared pieces of the difftrans command's subcommands: the registration
// signature, JSON output, progress and warnings on stderr.
#pragma once

#include <CLI/CLI.hpp>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>
#include <unistd.h>

#include "difftrans/io/json.hpp"

namespace difftrans::cli {

// Every subcommand file defines `void add_NAME(CLI::App& app)`, which adds
// its subcommand (options, --help, callback) to the application.
using AddCommand = void (*)(CLI::App&);

// Progress and warnings go to stderr, results to stdout. On a terminal a long
// fit keeps one status line redrawn in place (long_run.hpp: ProgressMeter);
// progress() and warn() clear it first, and the meter redraws it afterwards.
inline bool terminal() {
  static const bool is_tty = [] {
    const char* term = std::getenv("TERM");
    return isatty(STDERR_FILENO) == 1 && !(term && std::string(term) == "dumb");
  }();
  return is_tty;
}
namespace detail {
inline bool status_line_shown = false;
}
inline void clear_status_line() {
  if (detail::status_line_shown) std::cerr << "\r\x1b[K";
  detail::status_line_shown = false;
}
inline void status_line(const std::string& line) {
  std::cerr << '\r' << line << "\x1b[K" << std::flush;
  detail::status_line_shown = true;
}
inline void progress(const std::string& line) {
  clear_status_line();
  std::cerr << line << std::endl;
}
inline void warn(const std::string& line) {
  clear_status_line();
  std::cerr << "warning: " << line << std::endl;
}

// Prints the JSON result to stdout and, when `out` is given, writes it there.
// Non-finite numbers (an infinite PSNR) are written as null.
inline void emit_json(const io::Json& json, const std::optional<std::filesystem::path>& out) {
  std::cout << json.dump(2) << std::endl;
  if (out) io::write_json(*out, json);
}

}  // namespace difftrans::cli
