# Finds the libraries of the optional io/metrics part (meshes, images, scene
# directories, metrics) and defines the INTERFACE target difftrans::io.
# All of them are Debian packages; scripts/install-deps.sh installs them.

# stb, nanoflann and tinyobjloader: imported targets difftrans::stb,
# difftrans::nanoflann, difftrans::tinyobjloader (see DifftransIODeps.cmake).
include(DifftransIODeps)
find_package(OpenEXR CONFIG QUIET)
find_package(nlohmann_json CONFIG QUIET)
find_package(CLI11 CONFIG QUIET)
find_package(Threads REQUIRED)

set(_difftrans_io_missing "")
if(NOT TARGET difftrans::stb)
  list(APPEND _difftrans_io_missing "stb (libstb-dev)")
endif()
if(NOT TARGET difftrans::tinyobjloader)
  list(APPEND _difftrans_io_missing "tinyobjloader (libtinyobjloader-dev)")
endif()
if(NOT TARGET OpenEXR::OpenEXR)
  list(APPEND _difftrans_io_missing "OpenEXR (libopenexr-dev)")
endif()
if(NOT TARGET nlohmann_json::nlohmann_json)
  list(APPEND _difftrans_io_missing "nlohmann_json (nlohmann-json3-dev)")
endif()
if(NOT TARGET difftrans::nanoflann)
  list(APPEND _difftrans_io_missing "nanoflann (libnanoflann-dev)")
endif()

if(_difftrans_io_missing)
  list(JOIN _difftrans_io_missing ", " _difftrans_io_missing_text)
  message(WARNING "difftrans::io is not built; missing: ${_difftrans_io_missing_text}. "
                  "Run scripts/install-deps.sh.")
  return()
endif()

add_library(difftrans_io INTERFACE)
add_library(difftrans::io ALIAS difftrans_io)
set_target_properties(difftrans_io PROPERTIES EXPORT_NAME io)
target_link_libraries(difftrans_io INTERFACE
  difftrans::difftrans difftrans::stb difftrans::nanoflann difftrans::tinyobjloader OpenEXR::OpenEXR
  nlohmann_json::nlohmann_json Threads::Threads)

# The io and metrics tests link it (see tests/CMakeLists.txt).
set(DIFFTRANS_TEST_LIBS_io difftrans::io)
set(DIFFTRANS_TEST_LIBS_metrics difftrans::io)
