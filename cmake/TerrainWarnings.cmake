# Warnings for our own targets only (call terrain_warnings(target)); third-party headers are SYSTEM.
function(terrain_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion
                         -Wno-missing-field-initializers)
endfunction()
