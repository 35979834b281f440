# Fails if a file of a layer includes a header of a layer above it
# (docs/architecture.md): dependencies point one way,
# app -> driver -> io, input -> mpm -> material -> abi.
#   cmake -DROOT=<source dir> -P check_layers.cmake
# Each layer lists the talus/<area>/ headers its files may not include.
cmake_minimum_required(VERSION 3.25) # IN_LIST
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
    file(STRINGS ${f} includes REGEX "^[ \t]*#[ \t]*include")
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
# Inside the solver (core/src/mpm, docs/architecture.md, "The solver's
# folders"): the method sees the machinery only through the few headers
# named below. Each folder lists the folders it may not include from and,
# of those, the headers it may all the same.
set(solver ${ROOT}/core/src/mpm)
set(solver_forbidden_method "kernels/;ranks/")
set(solver_allowed_method "kernels/isa.hpp;kernels/lanes.hpp")
set(solver_forbidden_kernels "method/;ranks/;profile/;simulation_state.hpp")
set(solver_allowed_kernels "method/p2g.hpp;method/g2p.hpp;method/transfer.hpp")
set(solver_forbidden_parallel "method/;kernels/;ranks/;profile/;state/;simulation_state.hpp")
set(solver_allowed_parallel "state/grid.hpp")
set(solver_forbidden_ranks "method/;kernels/;profile/;parallel/")
set(solver_allowed_ranks "")
set(solver_forbidden_state "method/;kernels/;ranks/;profile/;parallel/;simulation_state.hpp")
set(solver_allowed_state "parallel/parallel.hpp")
set(solver_forbidden_profile "method/;kernels/;ranks/;state/;simulation_state.hpp")
set(solver_allowed_profile "method/g2p.hpp")
foreach(folder method kernels parallel ranks state profile)
  file(GLOB files ${solver}/${folder}/*.cpp ${solver}/${folder}/*.hpp)
  if(NOT files)
    message(FATAL_ERROR "no files found in ${solver}/${folder}")
  endif()
  foreach(f IN LISTS files)
    # Any spelling of an include: indented, with <> (src/mpm is on the
    # include path), or relative to the file's folder ("../kernels/...").
    file(STRINGS ${f} includes REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]")
    foreach(inc IN LISTS includes)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*[<\"]([^\">]*)[\">].*" "\\1" header
        "${inc}")
      string(REGEX REPLACE "^(\\.\\./)+" "" header "${header}")
      if(header IN_LIST solver_allowed_${folder})
        continue()
      endif()
      foreach(bad IN LISTS solver_forbidden_${folder})
        string(FIND "${header}" "${bad}" at)
        if(at EQUAL 0)
          string(APPEND failures "\n  ${f} (solver folder ${folder}): ${inc}")
        endif()
      endforeach()
    endforeach()
  endforeach()
endforeach()

if(failures)
  message(FATAL_ERROR "includes against the layering:${failures}")
endif()
message(STATUS "layers: every include points down")
