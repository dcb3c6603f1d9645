# rcand_add_plugin(<target> MANIFEST <file.json> SOURCES <src>... [OUTPUT_DIR <dir>] [ALLOW_UNDEFINED] [NO_EXPORT_CHECK]
#                  [INSTALL_COMPONENT <component>] [INSTALL_DESTINATION <dir>])
#
# Builds an rcand plugin: a MODULE library named as the manifest's "library", and -Wl,--no-undefined (a missing
# symbol fails the build, never the robot). The manifest is copied next to the library, so the output directory is a
# complete plugin directory.
#
# Isolation: two vendors who start from the same template ship plugins with identical C++ names. rcand dlopens each
# RTLD_LOCAL, but g++ binds a symbol it marks STB_GNU_UNIQUE (a class-static, an inline variable, a function's static
# local in a template) process-wide whatever the dlopen flags, so the second plugin would use the first one's. Every
# plugin is therefore built with hidden visibility and -fno-gnu-unique, linked with a version script that exports the
# entry symbol alone, and checked after the link: any other exported symbol fails the build (NO_EXPORT_CHECK: only
# for test fixtures that break the contract on purpose).
#
# Install: the library and its manifest install together (one plugin directory when installed too) into
# INSTALL_DESTINATION, else RCAND_INSTALL_PLUGIN_DIR (in the rcand tree), else <libdir>/rcand/plugins under the prefix:
# the packaged directory /usr/lib/<multiarch>/rcand/plugins for a .deb (prefix /usr), /usr/local/lib/rcand/plugins
# for an admin install - both directories rcand searches. Out of the rcand tree (a vendor build against the installed
# SDK) a plugin installs by default, as the component named INSTALL_COMPONENT or else the target (CPack-ready: one
# component per plugin); in the tree only with INSTALL_COMPONENT.
set(_RCAND_PLUGIN_CMAKE_DIR ${CMAKE_CURRENT_LIST_DIR} CACHE INTERNAL "where RcandPluginExports.cmake is")

function(rcand_add_plugin target)
  cmake_parse_arguments(PLUGIN "ALLOW_UNDEFINED;NO_EXPORT_CHECK" "MANIFEST;OUTPUT_DIR;INSTALL_COMPONENT;INSTALL_DESTINATION" "SOURCES" ${ARGN})
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
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(${target} PRIVATE -fno-gnu-unique)
  endif()
  set(_exports ${CMAKE_CURRENT_BINARY_DIR}/${target}.exports)
  file(WRITE ${_exports} "{ global: rcand_plugin_entry_v*; local: *; };\n")
  target_link_options(${target} PRIVATE -Wl,--version-script=${_exports})
  set_property(TARGET ${target} APPEND PROPERTY LINK_DEPENDS ${_exports})
  if(NOT PLUGIN_ALLOW_UNDEFINED)
    target_link_options(${target} PRIVATE -Wl,--no-undefined)
  endif()
  if(CMAKE_NM AND NOT PLUGIN_NO_EXPORT_CHECK)
    add_custom_command(TARGET ${target} POST_BUILD VERBATIM
      COMMAND ${CMAKE_COMMAND} -DNM=${CMAKE_NM} -DLIBRARY=$<TARGET_FILE:${target}>
              -P ${_RCAND_PLUGIN_CMAKE_DIR}/RcandPluginExports.cmake)
  endif()
  get_filename_component(_manifest_name ${_manifest} NAME)
  configure_file(${_manifest} ${PLUGIN_OUTPUT_DIR}/${_manifest_name} COPYONLY)
  set_property(TARGET ${target} PROPERTY RCAND_MANIFEST ${_manifest})
  if(NOT PLUGIN_INSTALL_COMPONENT AND NOT DEFINED RCAND_INSTALL_PLUGIN_DIR)
    set(PLUGIN_INSTALL_COMPONENT ${target})  # a vendor build: installs by default
  endif()
  if(PLUGIN_INSTALL_COMPONENT)
    if(PLUGIN_INSTALL_DESTINATION)
      set(_destination ${PLUGIN_INSTALL_DESTINATION})
    elseif(DEFINED RCAND_INSTALL_PLUGIN_DIR)
      set(_destination ${RCAND_INSTALL_PLUGIN_DIR})
    else()
      include(GNUInstallDirs)
      set(_destination ${CMAKE_INSTALL_LIBDIR}/rcand/plugins)
    endif()
    install(TARGETS ${target} LIBRARY DESTINATION ${_destination} COMPONENT ${PLUGIN_INSTALL_COMPONENT})
    install(FILES ${_manifest} DESTINATION ${_destination} COMPONENT ${PLUGIN_INSTALL_COMPONENT})
    set_property(GLOBAL APPEND PROPERTY RCAND_INSTALL_COMPONENTS ${PLUGIN_INSTALL_COMPONENT})
  endif()
  # Lets a project make its tests depend on every plugin it builds.
  set_property(GLOBAL APPEND PROPERTY RCAND_PLUGIN_TARGETS ${target})
endfunction()
