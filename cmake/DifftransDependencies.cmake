# Finds the dependencies of the core headers (GLM) and of the tests,
# benchmarks and examples (doctest, Google Benchmark; tinygltf for difftrans
# export, pugixml for the check of its Mitsuba scenes). scripts/install-deps.sh
# installs all of them from Debian packages.
include(GNUInstallDirs)
find_package(glm REQUIRED)

if(DIFFTRANS_BUILD_TESTS)
  find_package(doctest REQUIRED)
endif()
if(DIFFTRANS_BUILD_BENCH)
  find_package(benchmark REQUIRED)
endif()
if(DIFFTRANS_BUILD_EXAMPLES)
  # Debian's libtinygltf-dev: the implementation compiled in libtinygltf.so, a CMake config
  find_package(TinyGLTF CONFIG QUIET)
  if(DIFFTRANS_BUILD_TESTS)
    find_package(pugixml CONFIG QUIET)
  endif()
endif()
