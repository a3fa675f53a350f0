# Finds the libraries of the optional io/metrics part (meshes, images, scene
# directories, metrics) and defines the INTERFACE target difftrans::io.
# All of them are Debian packages; scripts/install-deps.sh installs them.

# stb_image / stb_image_write: Debian's libstb-dev ships the implementation
# compiled in libstb.so, so the headers are only declarations here.
find_path(DIFFTRANS_STB_INCLUDE_DIR NAMES stb_image.h stb_image_write.h PATH_SUFFIXES stb)
find_library(DIFFTRANS_STB_LIBRARY NAMES stb)
# tinyobjloader: Debian ships a CMake config; fall back to the bare library.
find_package(tinyobjloader CONFIG QUIET)
if(NOT TARGET tinyobjloader::tinyobjloader)
  find_path(DIFFTRANS_TINYOBJ_INCLUDE_DIR NAMES tiny_obj_loader.h)
  find_library(DIFFTRANS_TINYOBJ_LIBRARY NAMES tinyobjloader)
endif()
find_package(OpenEXR CONFIG QUIET)
find_package(nlohmann_json CONFIG QUIET)
find_path(DIFFTRANS_NANOFLANN_INCLUDE_DIR NAMES nanoflann.hpp)
find_package(CLI11 CONFIG QUIET)
find_package(Threads REQUIRED)

set(_difftrans_io_missing "")
if(NOT DIFFTRANS_STB_INCLUDE_DIR OR NOT DIFFTRANS_STB_LIBRARY)
  list(APPEND _difftrans_io_missing "stb (libstb-dev)")
endif()
if(NOT TARGET tinyobjloader::tinyobjloader AND (NOT DIFFTRANS_TINYOBJ_INCLUDE_DIR OR NOT DIFFTRANS_TINYOBJ_LIBRARY))
  list(APPEND _difftrans_io_missing "tinyobjloader (libtinyobjloader-dev)")
endif()
if(NOT TARGET OpenEXR::OpenEXR)
  list(APPEND _difftrans_io_missing "OpenEXR (libopenexr-dev)")
endif()
if(NOT TARGET nlohmann_json::nlohmann_json)
  list(APPEND _difftrans_io_missing "nlohmann_json (nlohmann-json3-dev)")
endif()
if(NOT DIFFTRANS_NANOFLANN_INCLUDE_DIR)
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
target_include_directories(difftrans_io SYSTEM INTERFACE
  ${DIFFTRANS_STB_INCLUDE_DIR} ${DIFFTRANS_NANOFLANN_INCLUDE_DIR})
target_link_libraries(difftrans_io INTERFACE
  difftrans::difftrans ${DIFFTRANS_STB_LIBRARY} OpenEXR::OpenEXR nlohmann_json::nlohmann_json Threads::Threads)
if(TARGET tinyobjloader::tinyobjloader)
  target_link_libraries(difftrans_io INTERFACE tinyobjloader::tinyobjloader)
else()
  target_include_directories(difftrans_io SYSTEM INTERFACE ${DIFFTRANS_TINYOBJ_INCLUDE_DIR})
  target_link_libraries(difftrans_io INTERFACE ${DIFFTRANS_TINYOBJ_LIBRARY})
endif()

# The io and metrics tests link it (see tests/CMakeLists.txt).
set(DIFFTRANS_TEST_LIBS_io difftrans::io)
set(DIFFTRANS_TEST_LIBS_metrics difftrans::io)
