# rcand_module(<name> SOURCES <files>... [DEPS <public libs>...] [PRIVATE_DEPS <libs>...]): one static library of
# rcand's own code. Every module includes by repository path ("libs/http/server.hpp", "kernel/safety/estop.hpp"),
# so an #include names the file it opens.
#
# The layering is the build's: a module's include root is the one of its layer (the top-level folder it is in), a
# directory in the build tree holding links to exactly the folders that layer may include, so a wrong #include fails
# to compile:
#   libs/      libs/ (and the SDK, through rcand::sdk)
#   kernel/    libs/, kernel/
#   services/  libs/, kernel/, services/
# rcanctl links libs only, so it sees libs/ and the SDK. Plugins see the SDK alone (plugins/CMakeLists.txt); tests
# and benchmarks see the whole tree. tests/check_kernel_shape.py checks the same rule on the sources.
set(RCAND_LAYER_libs libs)
set(RCAND_LAYER_kernel libs kernel)
set(RCAND_LAYER_services libs kernel services)
foreach(_layer libs kernel services)
  file(MAKE_DIRECTORY ${PROJECT_BINARY_DIR}/layers/${_layer})
  foreach(_folder ${RCAND_LAYER_${_layer}})
    file(CREATE_LINK ${PROJECT_SOURCE_DIR}/${_folder} ${PROJECT_BINARY_DIR}/layers/${_layer}/${_folder} SYMBOLIC)
  endforeach()
endforeach()

function(rcand_module name)
  cmake_parse_arguments(M "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  file(RELATIVE_PATH _where ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
  string(REGEX REPLACE "/.*" "" _layer "${_where}")
  if(NOT DEFINED RCAND_LAYER_${_layer})
    message(FATAL_ERROR "rcand_module(${name}) in ${_where}: modules live in libs/, kernel/ or services/")
  endif()
  add_library(${name} STATIC ${M_SOURCES})
  target_include_directories(${name} PUBLIC ${PROJECT_BINARY_DIR}/layers/${_layer})
  set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  target_link_libraries(${name} PUBLIC ${M_DEPS} PRIVATE ${M_PRIVATE_DEPS})
  rcand_strict(${name})
endfunction()
