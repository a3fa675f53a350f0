// Stateless random numbers: splitmix64's known outputs, the unit interval,
// and the bits of a float.
#include "difftrans/core/hash.hpp"

#include <cstdint>

#include <doctest/doctest.h>

TEST_CASE("splitmix64 gives the generator's published sequence from seed 0") {
  // the generator adds the constant before mixing: its first two outputs from state 0
  CHECK(difftrans::splitmix64(0) == 0xE220A8397B1DCDAFull);
  CHECK(difftrans::splitmix64(0x9E3779B97F4A7C15ull) == 0x6E789E6AA1B965F4ull);
}

TEST_CASE("unit_from_bits stays in [0, 1) and uses the top 53 bits") {
  CHECK(difftrans::unit_from_bits(0) == 0.0);
  CHECK(difftrans::unit_from_bits(~std::uint64_t(0)) < 1.0);
  CHECK(difftrans::unit_from_bits(std::uint64_t(1) << 63) == 0.5);
  CHECK(difftrans::unit_from_bits(0x7FF) == 0.0);  // the low 11 bits do not count
}

TEST_CASE("float_bits is the IEEE pattern") {
  CHECK(difftrans::float_bits(1.0f) == 0x3F800000u);
  CHECK(difftrans::float_bits(-2.0f) == 0xC0000000u);
  CHECK(difftrans::float_bits(0.0f) != difftrans::float_bits(-0.0f));
}
