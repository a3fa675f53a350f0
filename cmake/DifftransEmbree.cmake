# The host ray-tracing backend: Embree 3 and a thread pool. Defines
# difftrans::embree for programs and tests that trace on the host.
find_package(embree 3 REQUIRED)
find_package(Threads REQUIRED)
add_library(difftrans_embree INTERFACE)
add_library(difftrans::embree ALIAS difftrans_embree)
target_link_libraries(difftrans_embree INTERFACE difftrans::difftrans embree Threads::Threads)
set(DIFFTRANS_TEST_LIBS_accel difftrans::embree)
set(DIFFTRANS_TEST_LIBS_cuda difftrans::embree)  # the device kernels run on the host against the Embree passes
set(DIFFTRANS_TEST_LIBS_render difftrans::embree)
set(DIFFTRANS_BENCH_LIBS_trace difftrans::embree)
if(TARGET difftrans::io)
  list(APPEND DIFFTRANS_BENCH_LIBS_trace difftrans::io)
  list(APPEND DIFFTRANS_TEST_LIBS_render difftrans::io)
endif()
set(DIFFTRANS_BENCH_LIBS_bvh difftrans::embree)
