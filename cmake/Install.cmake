# `cmake --install`: the CLI, the Torch- and OpenCV-free parts of the library (map core, map file,
# queries, ontologies, fusion) with their headers, and a CMake package so that another project can
#   find_package(slamvdb REQUIRED)
#   target_link_libraries(app PRIVATE slamvdb::map slamvdb::store slamvdb::query)
# The parts are static libraries: their private dependencies (TBB, SQLite, zlib, fmt, yaml-cpp,
# nlohmann-json) are found again by slamvdbConfig.cmake for the link.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(SLAMVDB_INSTALLED_PARTS core map store query ontology fusion)
set(installed_targets)
foreach(part ${SLAMVDB_INSTALLED_PARTS})
  list(APPEND installed_targets slamvdb_${part})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/src/slamvdb/${part}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/slamvdb/${part}
          FILES_MATCHING PATTERN "*.hpp")
endforeach()
install(TARGETS ${installed_targets} EXPORT slamvdbTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS slamvdb_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The CLI's plugins (core/plugin_library.hpp), where it looks for them relative to its own folder.
get_property(slamvdb_plugins GLOBAL PROPERTY SLAMVDB_PLUGINS)
if(slamvdb_plugins)
  install(TARGETS ${slamvdb_plugins} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/slamvdb)
endif()

set(config_dir ${CMAKE_INSTALL_LIBDIR}/cmake/slamvdb)
install(EXPORT slamvdbTargets NAMESPACE slamvdb:: DESTINATION ${config_dir})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/slamvdbConfig.cmake.in
                              ${CMAKE_CURRENT_BINARY_DIR}/slamvdbConfig.cmake INSTALL_DESTINATION ${config_dir})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/slamvdbConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/slamvdbConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/slamvdbConfigVersion.cmake
        DESTINATION ${config_dir})
