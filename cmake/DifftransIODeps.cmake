# The libraries of the io part that ship no CMake package of their own, each
# wrapped in an imported target: difftrans::stb (stb_image / stb_image_write:
# Debian's libstb-dev compiles the implementation into libstb.so, so the
# headers are only declarations here), difftrans::nanoflann (headers) and
# difftrans::tinyobjloader (its CMake package when there is one, else the
# bare header and library). cmake/DifftransIO.cmake includes it when
# building; the installed difftransConfig.cmake includes it again, so the
# exported difftrans::io names these targets rather than the paths of the
# machine that built it.
find_path(DIFFTRANS_STB_INCLUDE_DIR NAMES stb_image.h stb_image_write.h PATH_SUFFIXES stb)
find_library(DIFFTRANS_STB_LIBRARY NAMES stb)
if(DIFFTRANS_STB_INCLUDE_DIR AND DIFFTRANS_STB_LIBRARY AND NOT TARGET difftrans::stb)
  add_library(difftrans::stb UNKNOWN IMPORTED)
  set_target_properties(difftrans::stb PROPERTIES
    IMPORTED_LOCATION "${DIFFTRANS_STB_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${DIFFTRANS_STB_INCLUDE_DIR}")
endif()

find_path(DIFFTRANS_NANOFLANN_INCLUDE_DIR NAMES nanoflann.hpp)
if(DIFFTRANS_NANOFLANN_INCLUDE_DIR AND NOT TARGET difftrans::nanoflann)
  add_library(difftrans::nanoflann INTERFACE IMPORTED)
  set_target_properties(difftrans::nanoflann PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${DIFFTRANS_NANOFLANN_INCLUDE_DIR}")
endif()

find_package(tinyobjloader CONFIG QUIET)
if(NOT TARGET difftrans::tinyobjloader)
  if(TARGET tinyobjloader::tinyobjloader)
    add_library(difftrans::tinyobjloader INTERFACE IMPORTED)
    set_target_properties(difftrans::tinyobjloader PROPERTIES
      INTERFACE_LINK_LIBRARIES tinyobjloader::tinyobjloader)
  else()
    find_path(DIFFTRANS_TINYOBJ_INCLUDE_DIR NAMES tiny_obj_loader.h)
    find_library(DIFFTRANS_TINYOBJ_LIBRARY NAMES tinyobjloader)
    if(DIFFTRANS_TINYOBJ_INCLUDE_DIR AND DIFFTRANS_TINYOBJ_LIBRARY)
      add_library(difftrans::tinyobjloader UNKNOWN IMPORTED)
      set_target_properties(difftrans::tinyobjloader PROPERTIES
        IMPORTED_LOCATION "${DIFFTRANS_TINYOBJ_LIBRARY}"
        INTERFACE_INCLUDE_DIRECTORIES "${DIFFTRANS_TINYOBJ_INCLUDE_DIR}")
    endif()
  endif()
endif()
