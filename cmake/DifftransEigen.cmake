# The sparse linear algebra part: Eigen 3 (Debian's libeigen3-dev, installed by
# scripts/install-deps.sh). Defines difftrans::eigen for the large-steps
# parameterization (optim/large_steps.hpp), the environment fit
# (scene/envmap_fit.hpp) and whatever else solves sparse systems. Optional:
# without Eigen those headers, their tests and benchmark, the pipeline and the
# difftrans command are left out of the build.
find_package(Eigen3 3.3 QUIET NO_MODULE)
if(NOT TARGET Eigen3::Eigen)
  message(WARNING "difftrans::eigen is not built (Eigen 3 not found: libeigen3-dev); left out: large steps "
                  "(optim/large_steps.hpp), the environment fit (scene/envmap_fit.hpp), the pipeline and the "
                  "difftrans command, and their tests")
  return()
endif()
add_library(difftrans_eigen INTERFACE)
add_library(difftrans::eigen ALIAS difftrans_eigen)
set_target_properties(difftrans_eigen PROPERTIES EXPORT_NAME eigen)
target_link_libraries(difftrans_eigen INTERFACE difftrans::difftrans Eigen3::Eigen)
set(DIFFTRANS_TEST_LIBS_optim difftrans::eigen)
set(DIFFTRANS_TEST_LIBS_geometry difftrans::eigen)
set(DIFFTRANS_TEST_LIBS_losses difftrans::eigen)
set(DIFFTRANS_BENCH_LIBS_large_steps difftrans::eigen)
set(DIFFTRANS_TEST_LIBS_scene difftrans::eigen)
list(APPEND DIFFTRANS_TEST_LIBS_render difftrans::eigen)
