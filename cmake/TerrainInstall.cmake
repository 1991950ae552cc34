# The installed package: export set `terrain` (terrain::format, terrain::remote, terrain::streamer; their install()
# rules sit in format/ and streamer/), terrainConfig.cmake + version file, and pkg-config files.
#   find_package(terrain CONFIG REQUIRED)
#   target_link_libraries(game PRIVATE terrain::streamer)
# Everything is relocatable: `cmake --install <build> --prefix <anywhere>` works without reconfiguring.
include(CMakePackageConfigHelpers)

set(TERRAIN_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/terrain)
install(EXPORT terrain NAMESPACE terrain:: FILE terrainTargets.cmake DESTINATION ${TERRAIN_CMAKE_DIR})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/terrainConfig.cmake.in
                              ${CMAKE_BINARY_DIR}/package/terrainConfig.cmake
                              INSTALL_DESTINATION ${TERRAIN_CMAKE_DIR} NO_SET_AND_CHECK_MACRO)
# 0.x: every minor version may change the API (0.2: ArchiveReader::payload() gave way to
# read_payload() and byte sources, issue 48; 0.3: the streamer's residency index replaced its dense
# index grids, issue 49), so a program asking for 0.2 does not get 0.3. The format itself is
# versioned in the archive header.
write_basic_package_version_file(${CMAKE_BINARY_DIR}/package/terrainConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/package/terrainConfig.cmake ${CMAKE_BINARY_DIR}/package/terrainConfigVersion.cmake
        DESTINATION ${TERRAIN_CMAKE_DIR})

# pkg-config: prefix found from the .pc file's own place (${pcfiledir}), so --prefix at install time works.
set(TERRAIN_PC_DIR ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
file(RELATIVE_PATH TERRAIN_PC_TO_PREFIX /prefix/${TERRAIN_PC_DIR} /prefix)
string(REGEX REPLACE "/$" "" TERRAIN_PC_TO_PREFIX "${TERRAIN_PC_TO_PREFIX}")
# A static terrain_format needs zstd and zlib on every link line (`pkg-config --libs` without --static).
if(BUILD_SHARED_LIBS)
  set(TERRAIN_PC_FORMAT_REQUIRES "")
  set(TERRAIN_PC_FORMAT_REQUIRES_PRIVATE "libzstd zlib")
else()
  set(TERRAIN_PC_FORMAT_REQUIRES "libzstd zlib")
  set(TERRAIN_PC_FORMAT_REQUIRES_PRIVATE "")
endif()
# The streamer opens paths and URLs through terrain_remote, which links libcurl with TERRAIN_HTTP.
set(TERRAIN_PC_REMOTE_REQUIRES "")
set(TERRAIN_PC_REMOTE_REQUIRES_PRIVATE "")
if(TERRAIN_HTTP AND BUILD_SHARED_LIBS)
  set(TERRAIN_PC_REMOTE_REQUIRES_PRIVATE "libcurl")
elseif(TERRAIN_HTTP)
  set(TERRAIN_PC_REMOTE_REQUIRES "libcurl")
endif()
foreach(pc terrain-format terrain-streamer)
  configure_file(${CMAKE_CURRENT_LIST_DIR}/${pc}.pc.in ${CMAKE_BINARY_DIR}/package/${pc}.pc @ONLY)
  install(FILES ${CMAKE_BINARY_DIR}/package/${pc}.pc DESTINATION ${TERRAIN_PC_DIR})
endforeach()
