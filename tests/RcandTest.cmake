# doctest's runner and main, compiled once for every test executable (and never merged into a unity source, where
# an earlier #include <doctest/doctest.h> would leave out the implementation).
add_library(rcand_doctest_main STATIC ${PROJECT_SOURCE_DIR}/tests/unit/doctest_main.cpp)
target_link_libraries(rcand_doctest_main PUBLIC doctest::doctest)
set_target_properties(rcand_doctest_main PROPERTIES UNITY_BUILD OFF)

# Test code is compiled at -O1 in optimised builds: it is three fifths of the normal build's compile time, and -O2
# took a test's unity file 26 s of CPU against 16.6 s at -O1 (g++ 12, acme_gripper_test). What ships - libraries,
# plugins, rcand - stays at the build type's -O2; sanitizer builds keep their own -O0 (RCAND_SANITIZE_FLAGS). Not -O0
# here: fortified libc calls and g++'s flow-based warnings need the optimiser.
set(RCAND_TEST_OPTIMIZE $<$<AND:$<NOT:$<BOOL:${RCAND_SANITIZE}>>,$<CONFIG:RelWithDebInfo,Release>>:-O1>)

# rcand_unit_test(<name> SOURCES <files>... LIBS <libs>...): one doctest executable, registered with CTest.
function(rcand_unit_test name)
  cmake_parse_arguments(T "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE rcand_doctest_main ${T_LIBS})
  target_include_directories(${name} PRIVATE ${PROJECT_SOURCE_DIR} ${PROJECT_SOURCE_DIR}/tests/support)  # the whole tree
  target_compile_definitions(${name} PRIVATE
    RCAND_SOURCE_DIR="${PROJECT_SOURCE_DIR}" RCAND_BINARY_DIR="${PROJECT_BINARY_DIR}"
    RCAND_PLUGIN_DIR="${RCAND_PLUGIN_OUTPUT_DIR}" RCAND_TEST_PLUGIN_DIR="${RCAND_TEST_PLUGIN_DIR}")
  rcand_strict(${name})
  target_compile_options(${name} PRIVATE ${RCAND_TEST_OPTIMIZE})  # plugins' tests live in their folders too
  rcand_without_fuzz_coverage(TARGETS ${name})  # among fuzzed code
  add_test(NAME ${name} COMMAND ${name})
endfunction()
