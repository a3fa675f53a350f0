// Stateless random numbers: a 64-bit mix (splitmix64's finalizer, Steele et
// al. 2014) and the uniform double in [0, 1) made from its top 53 bits. For
// choices that must repeat run to run and on any thread without a generator
// carried along: the radiance field's batches, the tracer's drawn branches.
#pragma once

#include <cstdint>
#include <cstring>

#include "difftrans/core/platform.hpp"

namespace difftrans {

DT_HOST_DEVICE inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

DT_HOST_DEVICE inline double unit_from_bits(std::uint64_t x) { return double(x >> 11) * (1.0 / 9007199254740992.0); }

// The bits of a float, for hashing it.
DT_HOST_DEVICE inline std::uint32_t float_bits(float x) {
  std::uint32_t b;
  memcpy(&b, &x, sizeof b);
  return b;
}

}  // namespace difftrans
