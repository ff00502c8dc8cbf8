# slamvdb_part(<name> [SOURCES <glob patterns>] [PUBLIC <deps>] [PRIVATE <deps>] [TEST_DEPS <deps>])
# Builds the static library slamvdb_<name> (alias slamvdb::<name>) from the .cpp files of the
# current folder (or the given patterns), minus its tests; records its *_test.cpp files and the
# extra libraries they need for the test executable.
function(slamvdb_part name)
  cmake_parse_arguments(P "" "" "SOURCES;PUBLIC;PRIVATE;TEST_DEPS;TESTS" ${ARGN})
  if(NOT P_SOURCES)
    set(P_SOURCES *.cpp)
  endif()
  if(NOT P_TESTS)
    set(P_TESTS *_test.cpp)
  endif()
  set(sources)
  foreach(pattern ${P_SOURCES})
    file(GLOB found CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/${pattern})
    list(APPEND sources ${found})
  endforeach()
  list(FILTER sources EXCLUDE REGEX ".*_test\\.cpp$")
  set(target slamvdb_${name})
  add_library(${target} STATIC ${sources})
  add_library(slamvdb::${name} ALIAS ${target})
  target_include_directories(${target} PUBLIC $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/src>
                                              $<INSTALL_INTERFACE:include>)
  target_link_libraries(${target} PUBLIC ${P_PUBLIC} PRIVATE ${P_PRIVATE})
  set_target_properties(${target} PROPERTIES POSITION_INDEPENDENT_CODE ON EXPORT_NAME ${name})
  set_property(GLOBAL APPEND PROPERTY SLAMVDB_PARTS ${target})

  set(tests)
  foreach(pattern ${P_TESTS})
    file(GLOB found CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/${pattern})
    list(APPEND tests ${found})
  endforeach()
  set_property(GLOBAL APPEND PROPERTY SLAMVDB_TEST_SOURCES ${tests})
  set_property(GLOBAL APPEND PROPERTY SLAMVDB_TEST_LIBRARIES ${P_TEST_DEPS})
endfunction()

# slamvdb_plugin(<name> <entry source> <libraries>...)
# Builds the plugin library libslamvdb_<name>.so (core/plugin_library.hpp: loaded at run time, only
# by the runs that need it) beside the executables, from <entry source> and the (static, PIC)
# <libraries>; only the entry point's symbols are exported. The CLI depends on it (it is built with
# `ninja slamvdb`) and it is installed in lib/slamvdb.
function(slamvdb_plugin name entry)
  set(target slamvdb_${name})
  add_library(${target} MODULE ${entry})
  target_link_libraries(${target} PRIVATE ${ARGN})
  set_target_properties(${target} PROPERTIES LIBRARY_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}
    CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON)
  # Every symbol resolved at link time: a missing one is a build error, not a failure at dlopen.
  # Not with clang's sanitizers (the fuzz tree): a shared object there leaves the runtime's symbols
  # (__asan_report_load1, ...) to the executable, which links the runtime statically.
  if(NOT (SLAMVDB_SANITIZE AND CMAKE_CXX_COMPILER_ID STREQUAL "Clang"))
    target_link_options(${target} PRIVATE -Wl,--no-undefined)
  endif()
  set_property(GLOBAL APPEND PROPERTY SLAMVDB_PLUGINS ${target})
endfunction()
