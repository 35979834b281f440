# The model's reference page as `talus plugin info MODEL --markdown` prints
# it must be the committed one (docs/materials/MODEL.md): regenerate with
#   talus plugin info MODEL --markdown --output-dir docs/materials
execute_process(COMMAND ${TALUS} plugin info ${MODEL} --markdown
  OUTPUT_VARIABLE generated RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "talus plugin info ${MODEL} --markdown failed (${rc}): ${err}")
endif()
if(NOT EXISTS ${PAGE})
  message(FATAL_ERROR "${PAGE} is missing; generate it with: talus plugin info ${MODEL} "
                      "--markdown --output-dir docs/materials")
endif()
file(READ ${PAGE} committed)
if(NOT generated STREQUAL committed)
  message(FATAL_ERROR "${PAGE} differs from what the plugin describes; regenerate it with: "
                      "talus plugin info ${MODEL} --markdown --output-dir docs/materials")
endif()
