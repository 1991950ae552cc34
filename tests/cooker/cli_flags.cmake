# Included at the end of tests/cooker/CMakeLists.txt (terrain-cook and terrain-inspect exist):
# the flags and outputs of terrain-cook tested from the command line.

# Flags through a cook, on inputs the tests write (raw heightmaps, GeoTIFFs).
terrain_test_executable(cooker_cli_flag_tests cooker SOURCES test_cli_flags.cpp LIBS cooker_test_util)
add_dependencies(cooker_cli_flag_tests terrain-cook)

set(_check ${CMAKE_SOURCE_DIR}/tests/format/cli_check.cmake)
set(_jacksboro /usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz)
set(_cli_dir ${CMAKE_BINARY_DIR}/cooker-cli-flags)
file(MAKE_DIRECTORY ${_cli_dir})
if(EXISTS ${_jacksboro})
  # --json on stdout: the report parses, names the input and gives level 5's 256 roots, an error
  # within the 0.5 m default tolerance at the finest level cooked (4) and every sample covered.
  add_test(NAME cooker.cli.json_report
           COMMAND ${CMAKE_COMMAND} -DCMD=$<TARGET_FILE:terrain-cook>
                   "-DARGS=${_jacksboro}|-o|${_cli_dir}/jacksboro.terrain|--crs|EPSG:4326|--heights-only|--json|--quiet"
                   -DEXPECT=0 -DUNCHANGED=${_jacksboro}
                   "-DJSON_CHECKS=inputs/0=jacksboro_fault_dem.npz|source/samples=^138632$|levels/5/nodes=^256$|levels/4/error_max_m=^0\\.[0-4]|levels/5/uncovered_samples=^0$"
                   -P ${_check})
  # --verify on a damaged copy of a real cooked archive (the default jacksboro cook): one byte of
  # the first payload flipped, and the file cut short. Exit 1 and a message matching `stderr_regex`.
  function(cooker_verify_damaged how damage stderr_regex)
    set(copy ${_cli_dir}/jacksboro-${how}.terrain)
    add_test(NAME cooker.cli.verify_${how}_real_archive
             COMMAND ${CMAKE_COMMAND} -DCMD=$<TARGET_FILE:terrain-inspect> "-DARGS=--verify|-q|${copy}" -DEXPECT=1
                     -DCOPY_FROM=${CMAKE_BINARY_DIR}/cooker-test-archives/jacksboro.terrain -DCOPY_TO=${copy}
                     -DDAMAGE=${damage} "-DSTDERR_REGEX=${stderr_regex}" -P ${_check})
  endfunction()
  cooker_verify_damaged(flipped flip:300 "payload_checksum: node [0-5]/[0-9]+/[0-9]+ at offset 128")
  cooker_verify_damaged(truncated truncate:100000 "truncated:.*file is 100000 bytes")
  set_tests_properties(cooker.cli.json_report cooker.cli.verify_flipped_real_archive
                       cooker.cli.verify_truncated_real_archive PROPERTIES LABELS cooker)
  set_tests_properties(cooker.cli.verify_flipped_real_archive cooker.cli.verify_truncated_real_archive
                       PROPERTIES FIXTURES_REQUIRED cooked_small)
endif()
# An unknown --bc-quality is a usage error naming the flag.
add_test(NAME cooker.cli.bad_bc_quality
         COMMAND ${CMAKE_COMMAND} -DCMD=$<TARGET_FILE:terrain-cook>
                 "-DARGS=/nonexistent/dem.tif|-o|${_cli_dir}/bad.terrain|--bc-quality|ultra" -DEXPECT=2
                 "-DSTDERR_REGEX=--bc-quality" -P ${_check})
set_tests_properties(cooker.cli.bad_bc_quality PROPERTIES LABELS cooker)
