cmake_policy(SET CMP0007 NEW)
# ctest fixture: cooks real DEMs into <build>/test-archives/ once per test run, for the streamer,
# viewer and cross-component tests (they skip with a message when an archive is absent).
# -D COOK=<terrain-cook> -D OUT=<dir> -D DATA=<shared data dir> -D SOURCE=<checkout> [-D PYTHON=<python3 with GDAL>]
if(NOT "$ENV{TERRAIN_DATA_DIR}" STREQUAL "")
  set(DATA "$ENV{TERRAIN_DATA_DIR}")
endif()
file(MAKE_DIRECTORY ${OUT})
# --tolerance 0.5 (the default of 1 m data; coarse DEMs default to 1/32 of their spacing): the
# streamer, viewer and package tests need trees several levels deep over these coarse DEMs.
set(jobs
  "jacksboro|/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz|--crs,EPSG:4326,--tolerance,0.5"
  "kilauea|${DATA}/kilauea_utm5n.tif|--tolerance,0.5"
  "tahoe|${DATA}/tahoe_lidar_bareearth.tif|"
  "slovenia|${DATA}/slovenia_TM1_564_146.tif|")
# lidar_world: the shared 1 m lidar tile inside a 30 m DEM made from it (cooker/bench/
# make_lidar_in_coarse.py: mirrored copies averaged over 30 m, 3 m higher), one cook of both: the
# viewer's crack test across the seam between the two grid families (issue 51).
set(lidar ${DATA}/slovenia_TM1_564_146.tif)
if(EXISTS ${lidar} AND PYTHON)
  execute_process(COMMAND ${PYTHON} ${SOURCE}/cooker/bench/make_lidar_in_coarse.py --lidar ${lidar}
                          --out-dir ${OUT}/lidar_world_inputs
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(rc EQUAL 0)
    list(APPEND jobs "lidar_world|${lidar}|${OUT}/lidar_world_inputs/coarse.tif")
  else()
    message(STATUS "test archive lidar_world: make_lidar_in_coarse.py failed (${rc}), skipped: ${err}")
  endif()
endif()
foreach(job IN LISTS jobs)
  string(REPLACE "|" ";" parts "${job}")
  list(GET parts 0 name)
  list(GET parts 1 src)
  list(LENGTH parts n)
  set(flags "")
  if(n GREATER 2)
    list(GET parts 2 flags)
    string(REPLACE "," ";" flags "${flags}")
  endif()
  if(NOT EXISTS ${src})
    # Jacksboro ships with Debian (setup.sh installs it) and the CLI tests draw it: its absence is an
    # error of the machine's setup. The shared DEMs are optional; their tests skip with a message.
    if(name STREQUAL "jacksboro")
      message(FATAL_ERROR "test archive ${name}: ${src} not found (run scripts/setup.sh: python-matplotlib-data)")
    endif()
    message(STATUS "test archive ${name}: input ${src} not found, skipped")
    continue()
  endif()
  execute_process(COMMAND ${COOK} ${src} -o ${OUT}/${name}.terrain ${flags} --quiet
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "cooking ${name} from ${src} failed (${rc}): ${out} ${err}")
  endif()
  message(STATUS "test archive ${name}: ${OUT}/${name}.terrain")
endforeach()
