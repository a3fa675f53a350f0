# Install rules and the package config, so that an installed copy is found
# with find_package(difftrans): difftrans::difftrans (the header-only core),
# and the parts this build made: difftrans::io, difftrans::host_tracing,
# difftrans::eigen (also asked for as components, e.g.
# find_package(difftrans COMPONENTS io host_tracing)).
include(CMakePackageConfigHelpers)

install(DIRECTORY include/difftrans DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# the presets' meshes and environment maps, where an installed difftrans
# command looks for them (examples/difftrans/views.hpp: data_dir)
install(DIRECTORY data/ DESTINATION ${CMAKE_INSTALL_DATADIR}/difftrans/data)

# What the package config must find again: one ON/OFF per part.
set(DIFFTRANS_EXPORTED_TARGETS difftrans)
foreach(part IN ITEMS io host_tracing eigen)
  if(TARGET difftrans_${part})
    list(APPEND DIFFTRANS_EXPORTED_TARGETS difftrans_${part})
    set(DIFFTRANS_PACKAGE_${part} ON)
  else()
    set(DIFFTRANS_PACKAGE_${part} OFF)
  endif()
endforeach()
set(DIFFTRANS_PACKAGE_EMBREE ${DIFFTRANS_HAVE_EMBREE})
install(TARGETS ${DIFFTRANS_EXPORTED_TARGETS} EXPORT difftransTargets)
install(EXPORT difftransTargets NAMESPACE difftrans:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/difftrans)

configure_package_config_file(
  ${CMAKE_CURRENT_SOURCE_DIR}/cmake/difftransConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/difftransConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/difftrans)
write_basic_package_version_file(
  ${CMAKE_CURRENT_BINARY_DIR}/difftransConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion ARCH_INDEPENDENT)
install(FILES
  ${CMAKE_CURRENT_BINARY_DIR}/difftransConfig.cmake
  ${CMAKE_CURRENT_BINARY_DIR}/difftransConfigVersion.cmake
  ${CMAKE_CURRENT_SOURCE_DIR}/cmake/DifftransIODeps.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/difftrans)
