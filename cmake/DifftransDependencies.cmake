# Finds the dependencies of the core headers (GLM) and of the tests,
# benchmarks and examples (doctest, Google Benchmark). scripts/install-deps.sh
# installs all of them from Debian packages.
include(GNUInstallDirs)
find_package(glm REQUIRED)

if(DIFFTRANS_BUILD_TESTS)
  find_package(doctest REQUIRED)
endif()
if(DIFFTRANS_BUILD_BENCH)
  find_package(benchmark REQUIRED)
endif()
