# rcand_add_plugin(<target> MANIFEST <file.json> SOURCES <src>... [OUTPUT_DIR <dir>] [ALLOW_UNDEFINED]
#                  [INSTALL_COMPONENT <component> [INSTALL_DESTINATION <dir>]])
#
# Builds an rcand plugin: a MODULE library named as the manifest's "library", with hidden visibility (only
# the entry symbol is exported) and -Wl,--no-undefined (a missing symbol fails the build, never the robot).
# The manifest is copied next to the library, so the output directory is a complete plugin directory.
# INSTALL_COMPONENT installs the library and its manifest together (one plugin directory when installed too):
# into INSTALL_DESTINATION, else RCAND_INSTALL_PLUGIN_DIR (in the rcand tree: <libdir>/rcand/plugins), else
# lib/rcand/plugins under the prefix (an admin-installed vendor plugin: /usr/local/lib/rcand/plugins).
function(rcand_add_plugin target)
  cmake_parse_arguments(PLUGIN "ALLOW_UNDEFINED" "MANIFEST;OUTPUT_DIR;INSTALL_COMPONENT;INSTALL_DESTINATION" "SOURCES" ${ARGN})
  if(NOT PLUGIN_MANIFEST)
    message(FATAL_ERROR "rcand_add_plugin(${target}): MANIFEST is required")
  endif()
  if(NOT PLUGIN_OUTPUT_DIR)
    if(DEFINED RCAND_PLUGIN_OUTPUT_DIR)
      set(PLUGIN_OUTPUT_DIR ${RCAND_PLUGIN_OUTPUT_DIR})
    else()
      set(PLUGIN_OUTPUT_DIR ${CMAKE_CURRENT_BINARY_DIR}/plugins)
    endif()
  endif()
  get_filename_component(_manifest ${PLUGIN_MANIFEST} ABSOLUTE)
  file(READ ${_manifest} _manifest_text)
  string(JSON _library GET "${_manifest_text}" library)
  get_filename_component(_library_name ${_library} NAME_WLE)

  add_library(${target} MODULE ${PLUGIN_SOURCES})
  target_link_libraries(${target} PRIVATE rcand::sdk)
  set_target_properties(${target} PROPERTIES
    PREFIX "" OUTPUT_NAME ${_library_name} SUFFIX ".so"
    LIBRARY_OUTPUT_DIRECTORY ${PLUGIN_OUTPUT_DIR}
    CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON)
  if(NOT PLUGIN_ALLOW_UNDEFINED)
    target_link_options(${target} PRIVATE -Wl,--no-undefined)
  endif()
  get_filename_component(_manifest_name ${_manifest} NAME)
  configure_file(${_manifest} ${PLUGIN_OUTPUT_DIR}/${_manifest_name} COPYONLY)
  set_property(TARGET ${target} PROPERTY RCAND_MANIFEST ${_manifest})
  if(PLUGIN_INSTALL_COMPONENT)
    if(PLUGIN_INSTALL_DESTINATION)
      set(_destination ${PLUGIN_INSTALL_DESTINATION})
    elseif(DEFINED RCAND_INSTALL_PLUGIN_DIR)
      set(_destination ${RCAND_INSTALL_PLUGIN_DIR})
    else()
      set(_destination lib/rcand/plugins)
    endif()
    install(TARGETS ${target} LIBRARY DESTINATION ${_destination} COMPONENT ${PLUGIN_INSTALL_COMPONENT})
    install(FILES ${_manifest} DESTINATION ${_destination} COMPONENT ${PLUGIN_INSTALL_COMPONENT})
    set_property(GLOBAL APPEND PROPERTY RCAND_INSTALL_COMPONENTS ${PLUGIN_INSTALL_COMPONENT})
  endif()
  # Lets a project make its tests depend on every plugin it builds.
  set_property(GLOBAL APPEND PROPERTY RCAND_PLUGIN_TARGETS ${target})
endfunction()
