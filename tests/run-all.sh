#!/usr/bin/env bash
# The whole test suite: installs dependencies, builds with Ninja, runs every test (units, fixture plugins,
# integration tests with real rcand processes), then the whole suite again built with sanitizers, then the fuzz
# targets for a bounded time. Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each stage's start, with the seconds elapsed so far: CI's log shows where the time goes.
stage() { echo "== run-all: $1 (at ${SECONDS} s)"; }
stage "dependencies"
packaging/install-deps.sh --checks
# The kernel stays a microkernel: size, function length, layering, capability names (tests/check_kernel_shape.py).
stage "kernel shape"
python3 tests/check_kernel_shape_test.py
python3 tests/check_kernel_shape.py
# Unity builds (CMake merges each target's sources, 8 at a time): Beast, Asio, JSON and doctest are parsed and
# instantiated once per batch instead of once per file, which takes the clean normal build from ~12 to ~7 minutes
# on 2 cores. Developers' own builds stay per-file (fast incremental rebuilds); this keeps the code unity-clean.
stage "normal build"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_UNITY_BUILD=ON -DRCAND_BUILD_TESTS=ON \
      -DRCAND_BUILD_BENCH=ON > /dev/null
cmake --build build
# Style on the last commit's changed lines (clang-format) and files (clang-tidy). clang-tidy reads the per-file
# compile commands of a configure-only, non-unity tree (the unity build's merge the sources).
stage "style of the last commit"
if git rev-parse -q --verify HEAD~1 > /dev/null; then
  cmake -S . -B build-lint -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRCAND_BUILD_TESTS=ON -DRCAND_BUILD_BENCH=ON > /dev/null
  tests/check_style.sh HEAD~1 build-lint
else
  echo "no parent commit: skipped"
fi
stage "normal build: tests"
# CI runs as root on a machine that reaches Debian's mirror: the clean-root package test must run, never skip.
RCAND_REQUIRE_LIFECYCLE=1 ctest --test-dir build --output-on-failure --timeout 600
# The soak's 20-second smoke run (bench/soak, normal build only): any error fails the suite.
stage "soak smoke run"
bench/soak/run-soak.sh build --smoke
# The arm64 packages: cross-compiled (Debian's cross toolchain, arm64 multiarch libraries), smoke-run under qemu-user.
stage "arm64 packages"
packaging/build-arm64.sh build-arm64

# The sanitizer build: clang-14 with ASan + UBSan (and libFuzzer coverage), the whole suite again (the packaging
# test only runs above). Any report, in a test or in an rcand it started, fails the suite.
stage "sanitizer build"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
cmake -S . -B build-sanitize -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang-14 \
      -DCMAKE_CXX_COMPILER=clang++-14 -DRCAND_FUZZ=ON -DRCAND_BUILD_TESTS=ON -DRCAND_BUILD_BENCH=OFF -DCMAKE_UNITY_BUILD=ON \
      > /dev/null
cmake --build build-sanitize
stage "sanitizer build: tests"
ctest --test-dir build-sanitize --output-on-failure --timeout 600

# Every libFuzzer target of that build for a bounded time (RCAND_FUZZ_SECONDS each: 13 targets x 20 s stay under
# 5 min of fuzzing, about 3 min of wall time two at a time - 171 s measured on a loaded 2-core VM). The long
# campaign is tests/fuzz/campaign.sh, outside CI.
stage "fuzzing"
tests/fuzz/run.sh "${RCAND_FUZZ_SECONDS:-20}" build-sanitize
stage "all passed"
