# The host ray-tracing part: a closest-hit accelerator and a thread pool.
# Defines difftrans::host_tracing for the programs and tests that trace on the
# host (render::HostScene). Embree 3 (Debian's libembree-dev) is optional:
# when it is found the target links it and defines DIFFTRANS_HAVE_EMBREE=1, so
# HostScene traces with Embree; without it HostScene uses the portable BVH
# (accel/bvh.hpp), which answers the same closest-hit query. Configure with
# -DCMAKE_DISABLE_FIND_PACKAGE_embree=ON to leave Embree out of a build.
# Sets DIFFTRANS_HAVE_EMBREE.
find_package(embree 3 QUIET)
find_package(Threads REQUIRED)
add_library(difftrans_host_tracing INTERFACE)
add_library(difftrans::host_tracing ALIAS difftrans_host_tracing)
set_target_properties(difftrans_host_tracing PROPERTIES EXPORT_NAME host_tracing)
target_link_libraries(difftrans_host_tracing INTERFACE difftrans::difftrans Threads::Threads)
if(embree_FOUND AND TARGET embree)
  set(DIFFTRANS_HAVE_EMBREE ON)
  target_link_libraries(difftrans_host_tracing INTERFACE embree)
  target_compile_definitions(difftrans_host_tracing INTERFACE DIFFTRANS_HAVE_EMBREE=1)
  message(STATUS "difftrans: host tracing with Embree ${embree_VERSION}")
else()
  set(DIFFTRANS_HAVE_EMBREE OFF)
  message(STATUS "difftrans: host tracing with the portable BVH (Embree 3 not used; "
                 "the Embree tests and benchmarks are left out)")
endif()

set(DIFFTRANS_TEST_LIBS_accel difftrans::host_tracing)
set(DIFFTRANS_TEST_LIBS_cuda difftrans::host_tracing)  # the device kernels run on the host against the host passes
set(DIFFTRANS_TEST_LIBS_render difftrans::host_tracing)
set(DIFFTRANS_BENCH_LIBS_trace difftrans::host_tracing)
if(TARGET difftrans::io)
  list(APPEND DIFFTRANS_BENCH_LIBS_trace difftrans::io)
  list(APPEND DIFFTRANS_TEST_LIBS_render difftrans::io)
endif()
set(DIFFTRANS_BENCH_LIBS_bvh difftrans::host_tracing)
