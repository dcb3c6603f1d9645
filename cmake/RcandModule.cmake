# rcand_module(<name> SOURCES <files>... [DEPS <public libs>...] [PRIVATE_DEPS <libs>...]): one static library of
# rcand's own code. Every module includes by repository path ("libs/http/server.hpp", "kernel/safety/estop.hpp"),
# so an #include names the file it opens; tests/check_kernel_shape.py keeps the layering (kernel/ never includes
# services/ or plugins/, libs/ never includes kernel/).
function(rcand_module name)
  cmake_parse_arguments(M "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(${name} STATIC ${M_SOURCES})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR})
  set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  target_link_libraries(${name} PUBLIC ${M_DEPS} PRIVATE ${M_PRIVATE_DEPS})
  rcand_strict(${name})
endfunction()
