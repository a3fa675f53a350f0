// io::Error messages name the file and the line; the file helpers say why they fail.
#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

TEST_CASE("Error names the file and the line") {
  const io::Error with_line("scene/a.json", "bad thing", 12);
  CHECK(std::string(with_line.what()) == "scene/a.json:12: bad thing");
  CHECK(with_line.line() == 12);
  CHECK(with_line.reason() == "bad thing");
  CHECK(with_line.file() == fs::path("scene/a.json"));
  const io::Error without("b.ply", "truncated");
  CHECK(std::string(without.what()) == "b.ply: truncated");
  const std::runtime_error& base = without;  // catchable as a runtime_error
  CHECK(contains(base.what(), "b.ply"));
}

TEST_CASE("reading a missing file, a folder, writing into a missing folder") {
  TempDir dir;
  const auto missing = dir / "nope.txt";
  CHECK(error_of([&] { io::detail::read_file_text(missing); }) == missing.string() + ": file not found");
  CHECK(error_of([&] { io::detail::read_file_text(dir.path()); }) == dir.path().string() + ": is a directory, not a file");
  const auto nowhere = dir / "no/such/folder/out.bin";
  CHECK(error_of([&] { io::detail::write_file_bytes(nowhere, "x", 1); }) == nowhere.string() + ": cannot open for writing");
  write_text(dir / "a.txt", "hello\n");
  CHECK(io::detail::read_file_text(dir / "a.txt") == "hello\n");
  CHECK(io::detail::lower_extension("A/B.OBJ") == ".obj");
  CHECK(io::detail::lower_extension("noext") == "");
}

TEST_CASE("an unreadable file says so") {
  if (::geteuid() == 0) return;  // root reads everything
  TempDir dir;
  const auto locked = dir / "locked.obj";
  write_text(locked, "v 0 0 0\n");
  fs::permissions(locked, fs::perms::none);
  CHECK(error_of([&] { io::detail::read_file_text(locked); }) == locked.string() + ": cannot open for reading");
}
