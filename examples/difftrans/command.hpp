// Shared pieces of the difftrans command's subcommands: the registration
// signature, JSON output, progress and warnings on stderr.
#pragma once

#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "difftrans/io/json.hpp"

namespace difftrans::cli {

// Every subcommand file defines `void add_NAME(CLI::App& app)`, which adds
// its subcommand (options, --help, callback) to the application.
using AddCommand = void (*)(CLI::App&);

// Progress and warnings go to stderr, results to stdout.
inline void progress(const std::string& line) { std::cerr << line << std::endl; }
inline void warn(const std::string& line) { std::cerr << "warning: " << line << std::endl; }

// Prints the JSON result to stdout and, when `out` is given, writes it there.
// Non-finite numbers (an infinite PSNR) are written as null.
inline void emit_json(const io::Json& json, const std::optional<std::filesystem::path>& out) {
  std::cout << json.dump(2) << std::endl;
  if (out) io::write_json(*out, json);
}

}  // namespace difftrans::cli
