# doctest's runner and main, compiled once for every test executable (and never merged into a unity source, where
# an earlier #include <doctest/doctest.h> would leave out the implementation).
add_library(rcand_doctest_main STATIC ${PROJECT_SOURCE_DIR}/tests/unit/doctest_main.cpp)
target_link_libraries(rcand_doctest_main PUBLIC doctest::doctest)
set_target_properties(rcand_doctest_main PROPERTIES UNITY_BUILD OFF)

# rcand_unit_test(<name> SOURCES <files>... LIBS <libs>...): one doctest executable, registered with CTest.
function(rcand_unit_test name)
  cmake_parse_arguments(T "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE rcand_doctest_main ${T_LIBS})
  target_include_directories(${name} PRIVATE ${PROJECT_SOURCE_DIR}/tests/support)
  target_compile_definitions(${name} PRIVATE
    RCAND_SOURCE_DIR="${PROJECT_SOURCE_DIR}" RCAND_BINARY_DIR="${PROJECT_BINARY_DIR}"
    RCAND_PLUGIN_DIR="${RCAND_PLUGIN_OUTPUT_DIR}" RCAND_TEST_PLUGIN_DIR="${RCAND_TEST_PLUGIN_DIR}")
  rcand_strict(${name})
  rcand_without_fuzz_coverage(TARGETS ${name})  # plugins' tests live in their folders, among fuzzed code
  add_test(NAME ${name} COMMAND ${name})
endfunction()
