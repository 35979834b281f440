# talus_add_plugin(<name> SOURCES <src>... [OUTPUT_DIRECTORY <dir>])
#
# Builds a Talus material plugin: a MODULE library named talus_<name>.so that
# links only talus::sdk and exports only talus_material_entry. The loader
# finds plugins by that file name on the plugin search path.
#
# A project that sets no CMAKE_BUILD_TYPE (single-configuration generators)
# would compile the plugin at -O0 with assertions, about ten times slower in
# a run, without a word: the plugin is then built optimised (-O2, NDEBUG)
# and a message says so. Set CMAKE_BUILD_TYPE=Debug to debug a plugin.
set(_TALUS_PLUGIN_MAP "${CMAKE_CURRENT_LIST_DIR}/talus_plugin.map")

function(talus_add_plugin name)
  cmake_parse_arguments(ARG "" "OUTPUT_DIRECTORY" "SOURCES" ${ARGN})
  if(NOT ARG_SOURCES)
    message(FATAL_ERROR "talus_add_plugin(${name}): SOURCES is required")
  endif()
  add_library(${name} MODULE ${ARG_SOURCES})
  if(TARGET talus::sdk)
    target_link_libraries(${name} PRIVATE talus::sdk)
  else()
    message(FATAL_ERROR "talus_add_plugin: target talus::sdk not found; call find_package(Talus)")
  endif()
  set_target_properties(${name} PROPERTIES
    PREFIX ""
    OUTPUT_NAME "talus_${name}"
    CXX_VISIBILITY_PRESET hidden
    C_VISIBILITY_PRESET hidden
    VISIBILITY_INLINES_HIDDEN ON
    LINK_DEPENDS "${_TALUS_PLUGIN_MAP}")
  target_link_options(${name} PRIVATE
    "LINKER:--version-script=${_TALUS_PLUGIN_MAP}" "LINKER:--no-undefined")
  get_property(_multi GLOBAL PROPERTY GENERATOR_IS_MULTI_CONFIG)
  if(NOT CMAKE_BUILD_TYPE AND NOT _multi)
    target_compile_options(${name} PRIVATE -O2)
    target_compile_definitions(${name} PRIVATE NDEBUG)
    message(STATUS "talus_add_plugin(${name}): no CMAKE_BUILD_TYPE set, building it optimised "
                   "(-O2, NDEBUG); pass -DCMAKE_BUILD_TYPE=Debug for a debug build")
  endif()
  if(ARG_OUTPUT_DIRECTORY)
    set_target_properties(${name} PROPERTIES LIBRARY_OUTPUT_DIRECTORY "${ARG_OUTPUT_DIRECTORY}")
  endif()
endfunction()
