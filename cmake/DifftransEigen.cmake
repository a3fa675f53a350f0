# The sparse linear algebra part: Eigen 3 (Debian's libeigen3-dev, installed by
# scripts/install-deps.sh). Defines difftrans::eigen for the large-steps
# parameterization (optim/large_steps.hpp) and whatever else solves sparse systems.
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
add_library(difftrans_eigen INTERFACE)
add_library(difftrans::eigen ALIAS difftrans_eigen)
target_link_libraries(difftrans_eigen INTERFACE difftrans::difftrans Eigen3::Eigen)
set(DIFFTRANS_TEST_LIBS_optim difftrans::eigen)
set(DIFFTRANS_TEST_LIBS_geometry difftrans::eigen)
set(DIFFTRANS_TEST_LIBS_losses difftrans::eigen)
set(DIFFTRANS_BENCH_LIBS_large_steps difftrans::eigen)
set(DIFFTRANS_TEST_LIBS_scene difftrans::eigen)
list(APPEND DIFFTRANS_TEST_LIBS_render difftrans::eigen)
