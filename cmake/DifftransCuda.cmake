# The CUDA backend: enabled when nvcc is found (DIFFTRANS_CUDA=AUTO) or
# required (ON). Sets DIFFTRANS_HAVE_CUDA and the target
# difftrans_cuda_options with the flags every device translation unit needs.
set(DIFFTRANS_HAVE_CUDA OFF)
if(NOT DIFFTRANS_CUDA STREQUAL "OFF")
  include(CheckLanguage)
  if(NOT CMAKE_CUDA_COMPILER AND EXISTS /usr/local/cuda/bin/nvcc)
    set(CMAKE_CUDA_COMPILER /usr/local/cuda/bin/nvcc)
  endif()
  check_language(CUDA)
  if(CMAKE_CUDA_COMPILER)
    if(NOT DEFINED CMAKE_CUDA_ARCHITECTURES)
      # sm_90 (H100) machine code plus its PTX for newer GPUs.
      set(CMAKE_CUDA_ARCHITECTURES 90)
    endif()
    enable_language(CUDA)
    set(CMAKE_CUDA_STANDARD 17)
    set(CMAKE_CUDA_STANDARD_REQUIRED ON)
    find_package(CUDAToolkit REQUIRED)
    set(DIFFTRANS_HAVE_CUDA ON)
    add_library(difftrans_cuda_options INTERFACE)
    # GLM marks defaulted members __host__ __device__ (warning 20012).
    target_compile_options(difftrans_cuda_options INTERFACE
      $<$<COMPILE_LANGUAGE:CUDA>:--expt-relaxed-constexpr -diag-suppress=20012 -Xcompiler=-Wall>)
    message(STATUS "difftrans: CUDA backend ON (nvcc ${CMAKE_CUDA_COMPILER_VERSION}, sm ${CMAKE_CUDA_ARCHITECTURES})")
  elseif(DIFFTRANS_CUDA STREQUAL "ON")
    message(FATAL_ERROR "difftrans: DIFFTRANS_CUDA=ON but no CUDA compiler was found")
  else()
    message(STATUS "difftrans: CUDA backend OFF (nvcc not found)")
  endif()
endif()
