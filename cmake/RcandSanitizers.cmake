# Sanitizer and fuzzing builds.
#
# RCAND_SANITIZE=ON   ASan + UBSan on every target (g++ or clang). Any report aborts the process, so a test fails.
# RCAND_FUZZ=ON       (clang only, implies RCAND_SANITIZE) also instruments the product's code for libFuzzer
#                     (-fsanitize=fuzzer-no-link) and builds tests/fuzz: ONE build serves the sanitizer test run
#                     and the fuzz targets, which is what keeps CI inside its time budget.
#
# Sanitizer builds compile with RCAND_SANITIZE_FLAGS. Default -O0 -g1: clang 14 builds kernel/api/api.cpp with
# ASan + UBSan + fuzzer coverage in 14 s at -O0 -g1 against 25 s at -O1 -g1 (g++ -O2 -g: 21 s), which is what fits
# both builds in CI's 30 minutes; the tests are I/O-bound and barely notice, and line tables are all a symbolized
# stack trace needs. For long fuzzing runs configure a second build with -DRCAND_SANITIZE_FLAGS="-O1 -g1".
option(RCAND_SANITIZE "Build everything with ASan and UBSan" OFF)
option(RCAND_FUZZ "Build the libFuzzer targets (clang; implies RCAND_SANITIZE)" OFF)
set(RCAND_SANITIZE_FLAGS "-O0 -g1" CACHE STRING "Optimization and debug flags of sanitizer builds")

if(RCAND_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "RCAND_FUZZ needs clang (libFuzzer): configure with -DCMAKE_CXX_COMPILER=clang++-14 "
                        "-DCMAKE_C_COMPILER=clang-14")
  endif()
  set(RCAND_SANITIZE ON CACHE BOOL "" FORCE)
endif()

if(RCAND_SANITIZE)
  separate_arguments(_rcand_sanitize_flags UNIX_COMMAND "${RCAND_SANITIZE_FLAGS}")
  # After the build type's flags on the command line, so these win.
  add_compile_options(${_rcand_sanitize_flags} -fsanitize=address,undefined -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  add_link_options(-fsanitize=address,undefined)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    # clang links its runtime statically into executables only, so a plugin (a MODULE linked with
    # -Wl,--no-undefined) could not resolve __asan_*: use the shared runtime everywhere, found through an rpath.
    execute_process(COMMAND ${CMAKE_CXX_COMPILER} -print-file-name=libclang_rt.asan-${CMAKE_SYSTEM_PROCESSOR}.so
                    OUTPUT_VARIABLE _rcand_asan_runtime OUTPUT_STRIP_TRAILING_WHITESPACE)
    get_filename_component(_rcand_asan_runtime_dir ${_rcand_asan_runtime} DIRECTORY)
    add_link_options(-shared-libsan -Wl,-rpath,${_rcand_asan_runtime_dir})
    # -Werror is the g++ build's (the compiler developers build with). Warnings only clang has are still printed
    # here but do not fail this build, since nobody on g++ could see them coming.
    add_compile_options(-Wno-error=unused-private-field)
  endif()
endif()

# rcand_without_fuzz_coverage([TARGETS <target>...]): no libFuzzer coverage for these targets (or, without TARGETS,
# for what this directory and its subdirectories define from here on). For code no fuzz target runs - tests,
# rcanctl, benchmarks: its comparison hooks made those compile a third slower and run slower under ASan, for nothing.
function(rcand_without_fuzz_coverage)
  if(NOT RCAND_FUZZ)
    return()
  endif()
  cmake_parse_arguments(C "" "" "TARGETS" ${ARGN})
  if(NOT C_TARGETS)
    get_directory_property(_options COMPILE_OPTIONS)
    list(REMOVE_ITEM _options -fsanitize=fuzzer-no-link)
    set_directory_properties(PROPERTIES COMPILE_OPTIONS "${_options}")
  endif()
  foreach(_target IN LISTS C_TARGETS)
    get_target_property(_options ${_target} COMPILE_OPTIONS)
    list(REMOVE_ITEM _options -fsanitize=fuzzer-no-link)
    set_target_properties(${_target} PROPERTIES COMPILE_OPTIONS "${_options}")
  endforeach()
endfunction()

if(RCAND_FUZZ)
  # Coverage feedback from every library the targets reach (not from tests, rcanctl or the benchmarks:
  # rcand_without_fuzz_coverage). The fuzz executables link libFuzzer (the driver) as a plain archive rather than
  # with -fsanitize=fuzzer, which would put libstdc++ before the shared ASan runtime in the executable's library
  # list (ASan refuses to start then).
  add_compile_options(-fsanitize=fuzzer-no-link)
  execute_process(COMMAND ${CMAKE_CXX_COMPILER} -print-file-name=libclang_rt.fuzzer-${CMAKE_SYSTEM_PROCESSOR}.a
                  OUTPUT_VARIABLE RCAND_LIBFUZZER OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(NOT EXISTS ${RCAND_LIBFUZZER})
    message(FATAL_ERROR "RCAND_FUZZ: libFuzzer not found (${RCAND_LIBFUZZER}); install libclang-rt-14-dev")
  endif()
endif()
