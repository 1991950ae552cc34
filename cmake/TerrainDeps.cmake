# Third-party packages, all from Debian 12 (installed by scripts/setup.sh).
find_package(zstd CONFIG REQUIRED)          # zstd::libzstd_shared (no zstd::libzstd in 1.5.4)
find_package(ZLIB REQUIRED)                 # crc32 for checksums, gzip input
find_package(fmt CONFIG REQUIRED)
find_package(nlohmann_json CONFIG REQUIRED)
find_package(CLI11 CONFIG REQUIRED)
find_package(Threads REQUIRED)
find_package(PkgConfig REQUIRED)
# libcurl (libcurl4-openssl-dev): archives read from http(s):// URLs (format/remote).
if(TERRAIN_HTTP)
  find_package(CURL REQUIRED)
endif()

# OpenImageIO: its config lists /usr/include/opencv4 (needs libopencv-core-dev); strip it if absent.
find_package(OpenImageIO CONFIG REQUIRED)
if(NOT EXISTS /usr/include/opencv4 AND TARGET OpenImageIO::OpenImageIO)
  get_target_property(_oiio_inc OpenImageIO::OpenImageIO INTERFACE_INCLUDE_DIRECTORIES)
  list(REMOVE_ITEM _oiio_inc /usr/include/opencv4)
  set_target_properties(OpenImageIO::OpenImageIO PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_oiio_inc}")
endif()
find_package(OpenEXR CONFIG REQUIRED)
find_package(Imath CONFIG REQUIRED)

# GeographicLib: Debian ships no config file, use pkg-config.
find_package(GeographicLib CONFIG QUIET)
if(NOT TARGET GeographicLib::GeographicLib)
  pkg_check_modules(GeographicLib REQUIRED IMPORTED_TARGET geographiclib)
  add_library(GeographicLib::GeographicLib ALIAS PkgConfig::GeographicLib)
endif()

# libgeotiff + libtiff: no config or pkg-config file for geotiff on Debian.
find_package(TIFF REQUIRED)
find_path(GEOTIFF_INCLUDE_DIR geotiff/geotiff.h REQUIRED)
find_library(GEOTIFF_LIBRARY geotiff REQUIRED)
add_library(terrain_geotiff INTERFACE)
target_include_directories(terrain_geotiff SYSTEM INTERFACE ${GEOTIFF_INCLUDE_DIR} ${GEOTIFF_INCLUDE_DIR}/geotiff)
target_link_libraries(terrain_geotiff INTERFACE ${GEOTIFF_LIBRARY} TIFF::TIFF)

# GDAL (libgdal-dev): every raster input it reads (cooker/src/inputs/gdal/input_gdal.cpp, web_tile_source.cpp).
find_package(GDAL CONFIG REQUIRED)

# expat (libexpat1-dev): a VRT's XML read one source at a time (cooker/src/inputs/gdal/vrt_stream.cpp).
find_package(EXPAT REQUIRED)

# PROJ (libproj-dev): terrain-inspect's lon/lat datum conversion (format/tools/inspect_lonlat.cpp).
pkg_check_modules(proj REQUIRED IMPORTED_TARGET proj)
pkg_check_modules(libzip REQUIRED IMPORTED_TARGET libzip)
# libdeflate (libdeflate-dev): deflate-compressed GeoTIFF blocks (cooker/src/inputs/tiff_blocks.cpp), as GDAL inflates them.
pkg_check_modules(libdeflate REQUIRED IMPORTED_TARGET libdeflate)
pkg_check_modules(squish REQUIRED IMPORTED_TARGET libsquish)
# Debian 12's libsquish.pc has an empty prefix, so the target carries "-I/include", which CMake
# rejects at generate time: keep only include dirs that really hold squish.h.
get_target_property(_squish_inc PkgConfig::squish INTERFACE_INCLUDE_DIRECTORIES)
if(_squish_inc)
  set(_squish_inc_ok "")
  foreach(_d IN LISTS _squish_inc)
    if(EXISTS "${_d}/squish.h")
      list(APPEND _squish_inc_ok "${_d}")
    endif()
  endforeach()
  set_target_properties(PkgConfig::squish PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_squish_inc_ok}")
endif()
find_path(STB_INCLUDE_DIR stb/stb_dxt.h REQUIRED)

if(TERRAIN_BUILD_TESTS)
  find_package(GTest CONFIG REQUIRED)
  include(GoogleTest)
endif()
if(TERRAIN_BUILD_BENCHMARKS)
  find_package(benchmark CONFIG QUIET)
  # CharLS (JPEG-LS), optional: the peer-coder column of terrain-format-bench (libcharls-dev).
  # Debian ships a config file with target `charls`; fall back to a plain header/library search.
  find_package(charls CONFIG QUIET)
  if(NOT TARGET charls)
    find_path(CHARLS_INCLUDE_DIR charls/charls.h)
    find_library(CHARLS_LIBRARY charls)
    if(EXISTS "${CHARLS_INCLUDE_DIR}/charls/charls.h" AND CHARLS_LIBRARY)
      add_library(charls UNKNOWN IMPORTED)
      set_target_properties(charls PROPERTIES IMPORTED_LOCATION "${CHARLS_LIBRARY}"
                                              INTERFACE_INCLUDE_DIRECTORIES "${CHARLS_INCLUDE_DIR}")
    endif()
  endif()
endif()
if(TERRAIN_BUILD_VIEWER)
  find_package(Vulkan REQUIRED COMPONENTS glslc)
  pkg_check_modules(glfw3 REQUIRED IMPORTED_TARGET glfw3)
endif()
