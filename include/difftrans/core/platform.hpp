// Platform macros shared by host and device code: DT_HOST_DEVICE marks every
// function of the generic path so that nvcc compiles it for both sides.
#pragma once

#if defined(__CUDACC__)
#define DT_HOST_DEVICE __host__ __device__
#define DT_DEVICE __device__
#define DT_FORCEINLINE __forceinline__
#else
#define DT_HOST_DEVICE
#define DT_DEVICE
#if defined(__GNUC__) || defined(__clang__)
#define DT_FORCEINLINE inline __attribute__((always_inline))
#else
#define DT_FORCEINLINE inline
#endif
#endif

// True while nvcc compiles the device side of a translation unit.
#if defined(__CUDA_ARCH__)
#define DT_DEVICE_PASS 1
#else
#define DT_DEVICE_PASS 0
#endif
