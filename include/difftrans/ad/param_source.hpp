// A flat float array a scene or a grid reads its unknowns from: either through the
// pass's parameter reader (differentiable) or as plain constants (frozen).
#pragma once

#include <cstdint>

#include "difftrans/ad/glm.hpp"

namespace difftrans::ad {

// One flat array of scene data (texels, raw absorption, vertex coordinates).
// buffer >= 0: the array is buffer `buffer` of the pass's ParamSet and every
// read goes through reader.read(buffer, index) (a leaf for Var, tangents for
// Dual); `values` must then be that buffer's values. buffer < 0: the array is
// frozen and read as constants of S, so it costs no tape and no log entries.
struct ParamSource {
  const float* values = nullptr;
  std::int32_t size = 0;
  int buffer = -1;

  DT_HOST_DEVICE constexpr bool differentiable() const { return buffer >= 0; }
};

// Any reader works that offers read(int buffer, std::int32_t index) returning
// something convertible to S (ad::ParamReader<S> in the library, others in tests).
template <class S, class Reader>
DT_HOST_DEVICE DT_FORCEINLINE S load(Reader& reader, const ParamSource& src, std::int32_t index) {
  if (src.buffer >= 0) return S(reader.read(src.buffer, index));
  return S(src.values[index]);
}

// Three consecutive entries (an RGB triple or an xyz point) starting at 3 * item.
template <class S, class Reader>
DT_HOST_DEVICE DT_FORCEINLINE Vec3<S> load3(Reader& reader, const ParamSource& src, std::int32_t item) {
  const std::int32_t i = 3 * item;
  return Vec3<S>(load<S>(reader, src, i), load<S>(reader, src, i + 1), load<S>(reader, src, i + 2));
}

}  // namespace difftrans::ad
