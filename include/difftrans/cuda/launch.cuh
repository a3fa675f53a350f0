// Sends a functor over an index range to the GPU: the device side of
// parallel_for. Also a minimal owning device buffer. Compiled only by nvcc.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <stdexcept>
#include <string>

namespace difftrans::cuda {

// Throws with the CUDA error text (host-side only).
inline void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string(what) + ": " + cudaGetErrorString(e));
}

// Number of usable CUDA devices; 0 when there is no driver or no GPU.
inline int device_count() {
  int n = 0;
  if (cudaGetDeviceCount(&n) != cudaSuccess) {
    (void)cudaGetLastError();
    return 0;
  }
  return n;
}

template <class F>
__global__ void for_each_index(int n, F f) {
  const int i = int(blockIdx.x) * int(blockDim.x) + int(threadIdx.x);
  if (i < n) f(i);
}

// Runs f(i) for i in [0, n) on the device; f is copied by value.
template <class F>
void launch(int n, const F& f, int block = 128, cudaStream_t stream = 0) {
  if (n <= 0) return;
  for_each_index<<<(n + block - 1) / block, block, 0, stream>>>(n, f);
  check(cudaGetLastError(), "kernel launch");
}

// As for_each_index, for blocks of 64 threads, compiled so that MinBlocks
// of them fit a multiprocessor at once (ptxas caps the registers to fit:
// 16 blocks, 64 registers a thread; what does not fit in them spills).
template <int MinBlocks, class F>
__global__ void __launch_bounds__(64, MinBlocks) for_each_index_bounded(int n, F f) {
  const int i = int(blockIdx.x) * 64 + int(threadIdx.x);
  if (i < n) f(i);
}

// Runs f(i) for i in [0, n) on the device in blocks of 64 threads, with
// registers capped so that MinBlocks blocks are resident per multiprocessor.
template <int MinBlocks, class F>
void launch_bounded(int n, const F& f, cudaStream_t stream = 0) {
  if (n <= 0) return;
  for_each_index_bounded<MinBlocks><<<(n + 63) / 64, 64, 0, stream>>>(n, f);
  check(cudaGetLastError(), "kernel launch");
}

// An owning array in device memory.
template <class T>
class DeviceBuffer {
 public:
  explicit DeviceBuffer(std::size_t n) : n_(n) { check(cudaMalloc(&p_, n * sizeof(T) + 1), "cudaMalloc"); }
  ~DeviceBuffer() { cudaFree(p_); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& o) noexcept : p_(o.p_), n_(o.n_) { o.p_ = nullptr; o.n_ = 0; }
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept {
    if (this != &o) {
      cudaFree(p_);
      p_ = o.p_;
      n_ = o.n_;
      o.p_ = nullptr;
      o.n_ = 0;
    }
    return *this;
  }
  void upload(const T* host) { check(cudaMemcpy(p_, host, n_ * sizeof(T), cudaMemcpyHostToDevice), "upload"); }
  void download(T* host) const { check(cudaMemcpy(host, p_, n_ * sizeof(T), cudaMemcpyDeviceToHost), "download"); }
  T* data() { return p_; }
  const T* data() const { return p_; }
  std::size_t size() const { return n_; }

 private:
  T* p_ = nullptr;
  std::size_t n_;
};

}  // namespace difftrans::cuda
