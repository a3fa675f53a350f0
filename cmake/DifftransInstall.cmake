# Install rules and the package config, so that an installed copy is found
# with find_package(difftrans) and linked as difftrans::difftrans.
include(CMakePackageConfigHelpers)

install(DIRECTORY include/difftrans DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# the presets' meshes and environment maps, where an installed difftrans
# command looks for them (examples/difftrans/views.hpp: data_dir)
install(DIRECTORY data/ DESTINATION ${CMAKE_INSTALL_DATADIR}/difftrans/data)
install(TARGETS difftrans EXPORT difftransTargets)
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
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/difftrans)
