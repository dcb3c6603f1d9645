# rcand_unit_test(<name> SOURCES <files>... LIBS <libs>...): one doctest executable, registered with CTest.
function(rcand_unit_test name)
  cmake_parse_arguments(T "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${T_SOURCES} ${PROJECT_SOURCE_DIR}/tests/unit/doctest_main.cpp)
  target_link_libraries(${name} PRIVATE doctest::doctest ${T_LIBS})
  target_compile_definitions(${name} PRIVATE
    RCAND_SOURCE_DIR="${PROJECT_SOURCE_DIR}" RCAND_BINARY_DIR="${PROJECT_BINARY_DIR}"
    RCAND_PLUGIN_DIR="${RCAND_PLUGIN_OUTPUT_DIR}" RCAND_TEST_PLUGIN_DIR="${RCAND_TEST_PLUGIN_DIR}")
  rcand_strict(${name})
  add_test(NAME ${name} COMMAND ${name})
endfunction()
