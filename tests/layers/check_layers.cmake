# Fails if a file of a layer includes a header of a layer above it
# (docs/architecture.md): dependencies point one way,
# app -> driver -> io, input -> mpm -> material -> abi.
#   cmake -DROOT=<source dir> -P check_layers.cmake
# Each layer lists the talus/<area>/ headers its files may not include.
set(forbidden_material "talus/mpm/;talus/input/;talus/io/;talus/driver/;talus/plugin_check/;talus/sdk/;yaml-cpp/;Eigen/")
set(forbidden_mpm "talus/input/;talus/io/;talus/driver/;talus/plugin_check/;talus/sdk/;yaml-cpp/;Eigen/")
set(forbidden_input "talus/io/;talus/driver/;talus/plugin_check/")
set(forbidden_io "talus/input/;talus/driver/;talus/plugin_check/")
set(forbidden_base "talus/material/;talus/mpm/;talus/input/;talus/io/;talus/driver/;talus/plugin_check/")

set(failures "")
foreach(layer material mpm input io base)
  file(GLOB_RECURSE files
    ${ROOT}/core/src/${layer}/*.cpp ${ROOT}/core/src/${layer}/*.hpp
    ${ROOT}/core/include/talus/${layer}/*.hpp)
  if(layer STREQUAL "base")
    list(APPEND files ${ROOT}/core/include/talus/error.hpp ${ROOT}/core/include/talus/text.hpp)
  endif()
  if(NOT files)
    message(FATAL_ERROR "no files found for layer ${layer} under ${ROOT}")
  endif()
  foreach(f IN LISTS files)
    file(STRINGS ${f} includes REGEX "^#include")
    foreach(inc IN LISTS includes)
      foreach(bad IN LISTS forbidden_${layer})
        string(FIND "${inc}" "${bad}" at)
        if(NOT at EQUAL -1)
          string(APPEND failures "\n  ${f} (layer ${layer}): ${inc}")
        endif()
      endforeach()
    endforeach()
  endforeach()
endforeach()
if(failures)
  message(FATAL_ERROR "includes against the layering:${failures}")
endif()
message(STATUS "layers: every include points down")
