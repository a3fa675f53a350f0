// Reverse-mode automatic differentiation: a Tape<T> of index-based nodes in
// one fixed-capacity buffer (owned, or lent by the caller for device code),
// and Var<T>, a value plus its node index. No global tape, no allocation per
// operation; overflow is reported, never silent. Arithmetic lives in math.hpp.
#pragma once

#include <cstdint>
#include <type_traits>

#include "difftrans/ad/traits.hpp"

namespace difftrans::ad {

// One recorded operation: up to two parents with their partial derivatives.
// An unused parent slot points at the node itself with partial 0, so the
// backward sweep needs no branch and never funnels unrelated nodes through
// one memory cell. Index 0 is the tape's sink, the index of constants.
template <class T>
struct Node {
  std::int32_t a, b;
  T da, db;
};

template <class T>
struct Var {
  static_assert(std::is_floating_point_v<T>, "Var<T>: T must be float or double");
  using value_type = T;

  T value;
  std::int32_t index;  // node on the tape; 0 for a constant
  Tape<T>* tape;       // nullptr for a constant

  Var() = default;  // trivial, like float: GLM may keep it in unions
  template <class U, std::enable_if_t<std::is_arithmetic_v<U>, int> = 0>
  DT_HOST_DEVICE constexpr Var(U v) : value(T(v)), index(0), tape(nullptr) {}
  DT_HOST_DEVICE constexpr Var(T v, std::int32_t i, Tape<T>* t) : value(v), index(i), tape(t) {}

  DT_HOST_DEVICE constexpr bool is_constant() const { return tape == nullptr; }

  template <class U>
  DT_HOST_DEVICE Var& operator+=(const U& o) { return *this = *this + o; }
  template <class U>
  DT_HOST_DEVICE Var& operator-=(const U& o) { return *this = *this - o; }
  template <class U>
  DT_HOST_DEVICE Var& operator*=(const U& o) { return *this = *this * o; }
  template <class U>
  DT_HOST_DEVICE Var& operator/=(const U& o) { return *this = *this / o; }
};

template <class T>
class Tape {
 public:
  using value_type = T;
  static constexpr std::size_t bytes_per_node = sizeof(Node<T>) + sizeof(T);

  // Host: the tape owns one buffer of `capacity` nodes and adjoints.
  explicit Tape(std::int32_t capacity)
      : storage_(new unsigned char[std::size_t(capacity < 1 ? 1 : capacity) * bytes_per_node]) {
    bind(reinterpret_cast<Node<T>*>(storage_),
         reinterpret_cast<T*>(storage_ + std::size_t(capacity < 1 ? 1 : capacity) * sizeof(Node<T>)),
         capacity < 1 ? 1 : capacity);
  }

  // Host or device: the tape records into caller-owned arrays of `capacity`
  // nodes and adjoints (e.g. per-thread local arrays in a kernel).
  DT_HOST_DEVICE Tape(Node<T>* nodes, T* adjoints, std::int32_t capacity) { bind(nodes, adjoints, capacity); }

  Tape(const Tape&) = delete;
  Tape& operator=(const Tape&) = delete;

  DT_HOST_DEVICE ~Tape() {
#if !DT_DEVICE_PASS
    delete[] storage_;
#endif
  }

  // A new leaf (independent variable).
  DT_HOST_DEVICE Var<T> variable(T v) { return Var<T>(v, push_unary(size_, T(0)), this); }

  // Records one node; on overflow sets the flag and returns the sink, so the
  // result acts as a constant and the caller can detect it via overflowed().
  DT_HOST_DEVICE DT_FORCEINLINE std::int32_t push(std::int32_t a, T da, std::int32_t b, T db) {
    if (size_ >= capacity_) {
      overflow_ = true;
      return 0;
    }
    nodes_[size_] = Node<T>{a, b, da, db};
    if (zero_on_push_) adjoints_[size_] = T(0);
    return std::int32_t(size_++);
  }
  // One parent; the second slot points at the new node itself.
  DT_HOST_DEVICE DT_FORCEINLINE std::int32_t push_unary(std::int32_t a, T da) {
    return push(a, da, std::int32_t(size_), T(0));
  }

  // Reverse sweep from y with seed 1. Adjoints of all recorded nodes are
  // reset first. Returns false when the tape overflowed (gradients partial).
  DT_HOST_DEVICE bool backward(const Var<T>& y) {
    zero_adjoints();
    if (y.tape == this && y.index > 0) {
      adjoints_[y.index] = T(1);
      propagate(y.index);
    }
    return !overflow_;
  }

  // Vector-Jacobian products: zero_adjoints(), seed(y_k, w_k) for each output,
  // then propagate().
  DT_HOST_DEVICE void zero_adjoints() {
    for (std::ptrdiff_t i = 0; i < size_; ++i) adjoints_[i] = T(0);
  }
  DT_HOST_DEVICE void seed(const Var<T>& y, T w) {
    if (y.tape == this) adjoints_[y.index] += w;
  }
  DT_HOST_DEVICE void propagate() { propagate(std::int32_t(size_ - 1)); }
  DT_HOST_DEVICE void propagate(std::int32_t from) { propagate(from, 1); }
  // The sweep over the nodes from `from` down to `down_to` only: what they
  // pass to earlier nodes is added to those nodes' adjoints, which a later
  // sweep carries on (streamed reverse mode: render/tracer.hpp, trace_streamed).
  DT_HOST_DEVICE void propagate(std::int32_t from, std::int32_t down_to) {
    if (down_to < 1) down_to = 1;
    // Most nodes feed the node recorded just before them: that contribution
    // is carried in a register instead of a store and a reload, which would
    // put a store-to-load forwarding delay on the critical path of every node.
    T carry = T(0);
    for (std::int32_t i = from; i >= down_to; --i) {
      const T g = adjoints_[i] + carry;
      const Node<T> n = nodes_[i];
      const T ca = n.da * g;
      const bool chained = n.a == i - 1;
      carry = chained ? ca : T(0);
      if (!chained) adjoints_[n.a] += ca;
      adjoints_[n.b] += n.db * g;
      adjoints_[i] = g;  // last: overwrites what a self-pointing slot added (0 · inf would be NaN)
    }
    if (down_to > 1) adjoints_[down_to - 1] += carry;  // node 0 is the sink
  }
  // Streamed reverse mode: each node's adjoint starts at zero as it is
  // recorded (seeds and sweeps then add to it while later nodes are swept
  // back and cut), instead of zero_adjoints() before one sweep.
  DT_HOST_DEVICE void zero_on_push(bool on) { zero_on_push_ = on; }
  // Forgets the nodes from `m` on; unlike rewind, keeps the overflow flag.
  DT_HOST_DEVICE void truncate(std::int32_t m) {
    if (size_ > peak_) peak_ = size_;
    if (m >= 1 && m < size_) size_ = m;
  }
  // The most nodes the tape held since the last reset or rewind.
  DT_HOST_DEVICE std::int32_t peak() const { return std::int32_t(size_ > peak_ ? size_ : peak_); }

  // d(output)/d(x) after backward / propagate; 0 for constants and other tapes.
  DT_HOST_DEVICE T adjoint(const Var<T>& x) const {
    return (x.tape == this && x.index > 0 && x.index < size_) ? adjoints_[x.index] : T(0);
  }

  // Forget every node (keeps the buffer). Clears the overflow flag.
  DT_HOST_DEVICE void reset() { rewind(1); }
  // Checkpoints: record shared leaves once, then rewind to the mark per work item.
  DT_HOST_DEVICE std::int32_t mark() const { return std::int32_t(size_); }
  DT_HOST_DEVICE void rewind(std::int32_t m) {
    size_ = m < 1 ? 1 : m;
    peak_ = size_;
    overflow_ = false;
    nodes_[0] = Node<T>{0, 0, T(0), T(0)};
    adjoints_[0] = T(0);
  }

  DT_HOST_DEVICE std::int32_t size() const { return std::int32_t(size_); }
  DT_HOST_DEVICE std::int32_t capacity() const { return std::int32_t(capacity_); }
  DT_HOST_DEVICE bool overflowed() const { return overflow_; }
  DT_HOST_DEVICE std::size_t bytes_used() const { return std::size_t(size_) * bytes_per_node; }

 private:
  DT_HOST_DEVICE void bind(Node<T>* nodes, T* adjoints, std::int32_t capacity) {
    nodes_ = nodes;
    adjoints_ = adjoints;
    capacity_ = capacity;
    reset();
  }

  unsigned char* storage_ = nullptr;
  Node<T>* nodes_ = nullptr;
  T* adjoints_ = nullptr;
  // Wider than the node indices on purpose: a store into a Node cannot then
  // alias the counters, so they stay in registers while recording.
  std::ptrdiff_t size_ = 0;
  std::ptrdiff_t capacity_ = 0;
  std::ptrdiff_t peak_ = 0;
  bool overflow_ = false;
  bool zero_on_push_ = false;
};

template <class T>
DT_HOST_DEVICE constexpr T value_of(const Var<T>& x) { return x.value; }

template <class T>
DT_HOST_DEVICE constexpr Var<T> detach(const Var<T>& x) { return Var<T>(x.value); }

namespace detail {

// The two primitives every derivative rule of math.hpp is written with.
template <class T>
DT_HOST_DEVICE DT_FORCEINLINE Var<T> unary(const Var<T>& x, T v, T dx) {
  if (!x.tape) return Var<T>(v);
  return Var<T>(v, x.tape->push_unary(x.index, dx), x.tape);
}

template <class T>
DT_HOST_DEVICE DT_FORCEINLINE Var<T> binary(const Var<T>& a, const Var<T>& b, T v, T da, T db) {
  if (!a.tape) return unary(b, v, db);  // a constant side records no edge
  if (!b.tape) return unary(a, v, da);
  return Var<T>(v, a.tape->push(a.index, da, b.index, db), a.tape);
}

}  // namespace detail
}  // namespace difftrans::ad
