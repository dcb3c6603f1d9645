# docs/drivers.md is generated from the plugin manifests: regenerate it with the built rcand and fail when the file
# in the tree differs (ctest -R drivers_doc). To update it: build/kernel/rcand --describe --markdown
# --plugin-path build/plugins > docs/drivers.md
execute_process(COMMAND ${RCAND} --describe --markdown --plugin-path ${PLUGINS}
  OUTPUT_VARIABLE generated ERROR_VARIABLE errors RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "rcand --describe --markdown failed (${result}):\n${errors}")
endif()
file(READ ${DOC} current)
if(NOT generated STREQUAL current)
  file(WRITE ${OUT} "${generated}")
  message(FATAL_ERROR "docs/drivers.md differs from what the manifests say (diff -u ${DOC} ${OUT}); regenerate it:\n"
                      "  build/kernel/rcand --describe --markdown --plugin-path build/plugins > docs/drivers.md")
endif()
