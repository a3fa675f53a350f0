// Binary checkpoints: what is written reads back; a wrong tag, a short file,
// a count beyond the file or the caller's limit, or leftover bytes are
// refused; a failed write leaves the previous checkpoint in place.
#include "difftrans/io/checkpoint.hpp"

#include <cstdint>
#include <string>
#include <vector>

#include "io/fixtures.hpp"

using namespace dt_test;
namespace io = difftrans::io;

namespace {

void write_sample(const fs::path& path, int iteration) {
  io::CheckpointWriter w(path, "TESTCK01");
  w.text("run a");
  w.value(std::int32_t(iteration));
  w.value(1.5f);
  w.array(std::vector<float>{1.0f, 2.0f, 3.0f});
  w.array(std::vector<double>{});
  w.commit();
}

std::string bytes_of(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

}  // namespace

TEST_CASE("checkpoint: values, arrays and text read back in order") {
  TempDir dir;
  write_sample(dir / "c.bin", 7);
  CHECK_FALSE(fs::exists(dir / "c.bin.tmp"));
  io::CheckpointReader r(dir / "c.bin", "TESTCK01");
  REQUIRE(r.ok());
  std::string run;
  std::int32_t it = 0;
  float x = 0.0f;
  std::vector<float> a;
  std::vector<double> b{9.0};
  CHECK(r.text(run, 100));
  CHECK(r.value(it));
  CHECK(r.value(x));
  CHECK(r.array(a, 3));
  CHECK(r.array(b, 10));
  CHECK(r.complete());
  CHECK(run == "run a");
  CHECK(it == 7);
  CHECK(x == 1.5f);
  CHECK(a == std::vector<float>{1.0f, 2.0f, 3.0f});
  CHECK(b.empty());
}

TEST_CASE("checkpoint: absent file, other tag, counts beyond the limit or the file, truncation") {
  TempDir dir;
  CHECK_FALSE(io::CheckpointReader(dir / "none.bin", "TESTCK01").ok());
  write_sample(dir / "c.bin", 3);
  CHECK_FALSE(io::CheckpointReader(dir / "c.bin", "OTHERCK1").ok());
  {  // the caller's limit
    io::CheckpointReader r(dir / "c.bin", "TESTCK01");
    std::string run;
    CHECK_FALSE(r.text(run, 4));  // "run a" has 5 characters
    CHECK_FALSE(r.ok());
    std::int32_t it = -1;
    CHECK_FALSE(r.value(it));  // nothing is read after a failure
    CHECK(it == -1);
  }
  const std::string whole = bytes_of(dir / "c.bin");
  for (std::size_t cut = 0; cut < whole.size(); ++cut) {  // every truncation fails somewhere, never crashes
    write_text(dir / "t.bin", whole.substr(0, cut));
    io::CheckpointReader r(dir / "t.bin", "TESTCK01");
    std::string run;
    std::int32_t it = 0;
    float x = 0.0f;
    std::vector<float> a;
    std::vector<double> b;
    r.text(run, 100);
    r.value(it);
    r.value(x);
    r.array(a, 3);
    r.array(b, 10);
    CHECK_FALSE(r.complete());
  }
  {  // a count of 2^60 elements in a small file is refused before any allocation
    std::string huge = whole.substr(0, 8);
    const std::uint64_t n = std::uint64_t(1) << 60;
    huge.append(reinterpret_cast<const char*>(&n), sizeof n);
    write_text(dir / "h.bin", huge);
    io::CheckpointReader r(dir / "h.bin", "TESTCK01");
    std::vector<float> a;
    CHECK_FALSE(r.array(a, ~std::uint64_t(0)));
    CHECK(a.empty());
  }
  {  // bytes left over: not complete
    write_text(dir / "x.bin", whole + "junk");
    io::CheckpointReader r(dir / "x.bin", "TESTCK01");
    std::string run;
    std::int32_t it = 0;
    float x = 0.0f;
    std::vector<float> a;
    std::vector<double> b;
    CHECK((r.text(run, 100) && r.value(it) && r.value(x) && r.array(a, 3) && r.array(b, 10)));
    CHECK(r.ok());
    CHECK_FALSE(r.complete());
  }
}

TEST_CASE("checkpoint: a write that is not committed leaves the previous checkpoint") {
  TempDir dir;
  write_sample(dir / "c.bin", 1);
  const std::string before = bytes_of(dir / "c.bin");
  {
    io::CheckpointWriter w(dir / "c.bin", "TESTCK01");
    w.value(std::int32_t(2));
    // destroyed without commit(): as if the program died here
  }
  CHECK(bytes_of(dir / "c.bin") == before);
  write_sample(dir / "c.bin", 2);
  CHECK(bytes_of(dir / "c.bin") != before);
  CHECK(contains(error_of([&] { io::CheckpointWriter(dir / "no" / "such" / "c.bin", "TESTCK01"); }),
                 "cannot open the checkpoint for writing"));
}
