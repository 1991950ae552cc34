# terrain_test_executable(<target> <label> SOURCES <files...> LIBS <libraries...>): a GoogleTest
# executable built with the project's warnings, its tests discovered by ctest with label <label>.
# Used by tests/cooker and tests/surface.
function(terrain_test_executable target label)
  cmake_parse_arguments(PARSE_ARGV 2 arg "" "" "SOURCES;LIBS")
  add_executable(${target} ${arg_SOURCES})
  target_link_libraries(${target} PRIVATE ${arg_LIBS})
  terrain_warnings(${target})
  gtest_discover_tests(${target} DISCOVERY_MODE PRE_TEST PROPERTIES LABELS ${label})
endfunction()
