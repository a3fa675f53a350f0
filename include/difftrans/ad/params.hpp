// Differentiable parameter buffers. The scene reads every unknown (vertex
// coordinates, IoR, absorption voxels, environment texels) through a
// ParamReader<S>, which hands it out as the scalar of the pass:
//   float/double  a plain load;
//   Dual<T, N>    the value with tangent lanes taken from per-lane direction
//                 buffers (directional derivatives along chosen parameters);
//   Var<T>        a fresh leaf on the caller's tape, logged so that after the
//                 backward pass scatter() adds its adjoint into the buffer's
//                 gradient array.
// Only the parameters a ray touches become leaves, so a tape stays small.
#pragma once

#include <cmath>
#include <cstdint>

#include "difftrans/ad/dual.hpp"
#include "difftrans/ad/tape.hpp"

namespace difftrans::ad {

inline constexpr int max_param_buffers = 8;
inline constexpr int max_tangent_lanes = 8;

// One flat array of parameters (e.g. all vertex coordinates, x y z interleaved).
struct ParamBuffer {
  const float* values = nullptr;
  std::int32_t size = 0;
  float* gradient = nullptr;                            // reverse mode: adjoints are added here
  // Reverse mode: when set, adjoints are added here instead, in double. For
  // a small buffer that receives millions of adds (the IoR, a few absorption
  // values) a float sum loses the low bits of each add the same way every
  // time: on a grid-absorbing sphere at 512², depth 4, dL/dIoR summed per
  // branch in float lands 7e-4 off its double sum, a bias, not noise
  // (docs/cuda.md, "Summing the gradient").
  double* wide_gradient = nullptr;
  const float* tangents[max_tangent_lanes] = {nullptr};  // forward mode: lane l direction, or null (0)
};

// The buffers of one scene, addressed by a small id each.
struct ParamSet {
  ParamBuffer buffers[max_param_buffers];
};

namespace detail {
// Lock-free add of a float or double, for gradients scattered by many threads.
template <class T>
DT_HOST_DEVICE inline void atomic_add(T* p, T v) {
#if DT_DEVICE_PASS
  atomicAdd(p, v);
#else
  T expected = *p, desired;
  do {
    desired = expected + v;
  } while (!__atomic_compare_exchange(p, &expected, &desired, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED));
#endif
}
// Adds one adjoint into a buffer's gradient: its wide (double) array when it
// has one, otherwise its float array; nothing without either.
template <class T>
DT_HOST_DEVICE inline void add_gradient(const ParamBuffer& b, std::int32_t index, T a) {
  if (b.wide_gradient) atomic_add(b.wide_gradient + index, double(a));
  else if (b.gradient) atomic_add(b.gradient + index, float(a));
}
}  // namespace detail

// Plain scalars: loads.
template <class S>
class ParamReader {
 public:
  DT_HOST_DEVICE explicit ParamReader(const ParamSet* set) : set_(set) {}
  DT_HOST_DEVICE S read(int buffer, std::int32_t index) { return S(set_->buffers[buffer].values[index]); }
  DT_HOST_DEVICE const ParamSet* params() const { return set_; }

 private:
  const ParamSet* set_;
};

// Forward mode: each lane l carries the direction tangents[l].
template <class T, int N>
class ParamReader<Dual<T, N>> {
 public:
  DT_HOST_DEVICE explicit ParamReader(const ParamSet* set) : set_(set) {}
  DT_HOST_DEVICE Dual<T, N> read(int buffer, std::int32_t index) {
    const ParamBuffer& b = set_->buffers[buffer];
    Dual<T, N> v(b.values[index]);
    for (int l = 0; l < N && l < max_tangent_lanes; ++l)
      if (b.tangents[l]) v.grad[l] = T(b.tangents[l][index]);
    return v;
  }
  DT_HOST_DEVICE const ParamSet* params() const { return set_; }

 private:
  const ParamSet* set_;
};

// One leaf handed out by a reverse-mode reader.
struct LeafRecord {
  std::int32_t buffer;
  std::int32_t index;
  std::int32_t node;
};

// Reverse mode: leaves on the caller's tape, logged in a caller-owned array.
template <class T>
class ParamReader<Var<T>> {
 public:
  DT_HOST_DEVICE ParamReader(const ParamSet* set, Tape<T>* tape, LeafRecord* log, std::int32_t log_capacity)
      : set_(set), tape_(tape), log_(log), capacity_(log_capacity) {}

  DT_HOST_DEVICE Var<T> read(int buffer, std::int32_t index) {
    const Var<T> v = tape_->variable(T(set_->buffers[buffer].values[index]));
    if (count_ < capacity_) {
      log_[count_++] = LeafRecord{buffer, index, v.index};
    } else {
      overflow_ = true;
    }
    return v;
  }

  // After tape->backward / propagate: adds every logged leaf's adjoint, times
  // `scale`, into its buffer's gradient (atomically), then clears the log.
  DT_HOST_DEVICE void scatter(T scale = T(1)) {
    for (std::int32_t k = 0; k < count_; ++k) {
      const LeafRecord& r = log_[k];
      const T a = tape_->adjoint(Var<T>(T(0), r.node, tape_));
      if (a != T(0)) detail::add_gradient(set_->buffers[r.buffer], r.index, a * scale);
    }
    count_ = 0;
  }

  // Streamed reverse mode: scatter() for the leaves recorded at tape node
  // `mark` or later only (a suffix of the log: leaves are logged as they are
  // recorded), which are then forgotten; the earlier ones stay.
  DT_HOST_DEVICE void scatter_from(std::int32_t mark) {
    std::int32_t k = count_;
    while (k > 0 && log_[k - 1].node >= mark) {
      const LeafRecord& r = log_[--k];
      const T a = tape_->adjoint(Var<T>(T(0), r.node, tape_));
      if (a != T(0)) detail::add_gradient(set_->buffers[r.buffer], r.index, a);
    }
    count_ = k;
  }

  // After the sweep: Σ adjoint² over the logged leaves of one buffer (the
  // squared norm of this record's gradient w.r.t. that buffer).
  DT_HOST_DEVICE T adjoint_norm2(int buffer) const {
    T sum = T(0);
    for (std::int32_t k = 0; k < count_; ++k)
      if (log_[k].buffer == buffer) {
        const T a = tape_->adjoint(Var<T>(T(0), log_[k].node, tape_));
        sum += a * a;
      }
    return sum;
  }

  // scatter() with one scale per buffer (e.g. a per-ray clip of some buffers' gradient).
  DT_HOST_DEVICE void scatter_scaled(const T* scale_per_buffer) {
    for (std::int32_t k = 0; k < count_; ++k) {
      const LeafRecord& r = log_[k];
      const T a = tape_->adjoint(Var<T>(T(0), r.node, tape_));
      if (a != T(0)) detail::add_gradient(set_->buffers[r.buffer], r.index, a * scale_per_buffer[r.buffer]);
    }
    count_ = 0;
  }

  // scatter_scaled() with the norm of the gradient capped per clip class:
  // the buffers b with clip_class[b] = c (1 or 2; 0: no cap) share one L2
  // norm, scaled down to clip[c − 1] where it is above that (clip ≤ 0: no
  // cap). Returns bit c − 1 set for each class that was capped.
  DT_HOST_DEVICE int scatter_clipped(const std::int8_t* clip_class, const float* clip) {
    T scale[max_param_buffers];
    for (T& x : scale) x = T(1);
    int capped = 0;
    for (int c = 1; c <= 2; ++c) {
      const T cap = T(clip[c - 1]);
      if (!(cap > T(0))) continue;
      T n2 = T(0);
      for (int b = 0; b < max_param_buffers; ++b)
        if (clip_class[b] == c) n2 += adjoint_norm2(b);
      if (n2 > cap * cap) {
        for (int b = 0; b < max_param_buffers; ++b)
          if (clip_class[b] == c) scale[b] = cap / std::sqrt(n2);
        capped |= 1 << (c - 1);
      }
    }
    scatter_scaled(scale);
    return capped;
  }

  // Forget the log without scattering (e.g. when the tape is rewound).
  DT_HOST_DEVICE void clear() {
    count_ = 0;
    overflow_ = false;
  }
  DT_HOST_DEVICE std::int32_t size() const { return count_; }
  DT_HOST_DEVICE bool overflowed() const { return overflow_; }
  DT_HOST_DEVICE Tape<T>* tape() const { return tape_; }
  // The buffers read (their values serve a plain reader for constant parts of a pass).
  DT_HOST_DEVICE const ParamSet* params() const { return set_; }

 private:
  const ParamSet* set_;
  Tape<T>* tape_;
  LeafRecord* log_;
  std::int32_t capacity_;
  std::int32_t count_ = 0;
  bool overflow_ = false;
};

}  // namespace difftrans::ad
