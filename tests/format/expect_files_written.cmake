# expect_files_written(<file>...): in a -P script, fails (FATAL_ERROR) unless every file exists and
# is not empty. Used by tests/format/cli_check.cmake and tests/viewer/cli_check.cmake.
function(expect_files_written)
  foreach(f IN LISTS ARGN)
    if(NOT EXISTS ${f})
      message(FATAL_ERROR "${f} was not written")
    endif()
    file(SIZE ${f} size)
    if(size EQUAL 0)
      message(FATAL_ERROR "${f} is empty")
    endif()
  endforeach()
endfunction()
