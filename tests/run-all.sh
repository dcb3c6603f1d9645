#!/usr/bin/env bash
# The whole test suite: installs dependencies, builds with Ninja, runs every test (units, fixture plugins,
# integration tests with real rcand processes), then the suite again built with sanitizers (all but the two longest
# integration programs), then the fuzz targets for a bounded time, and the arm64 packages. Exits non-zero on any
# failure.
set -euo pipefail
cd "$(dirname "$0")/.."

# Each stage's start, with the seconds elapsed so far; at the end, pass or fail, every stage's duration (CI shows a
# log's tail: that is where to read where the time went).
timings=() current="" current_at=0
end_stage() {
  if [ -n "$current" ]; then timings+=("$(printf '%6d s  %s' $((SECONDS - current_at)) "$current")"); fi
  current=""
}
stage() { end_stage; current=$1 current_at=$SECONDS; echo "== run-all: $1 (at ${SECONDS} s)"; }

# Two builds run in the background, taking the CPU the foreground leaves: the arm64 packages from the start (their
# build root is mostly downloads), the sanitizer build from the normal tests on. At nice 19 they take only what the
# tests leave (a nice-0 task that wakes preempts them), so the tests' timing is the same as alone; the 2-core budget
# is what they save. Each runs in a session of its own (to be stopped as one on a failure), which the scheduler's
# autogroups would weigh as much as this one whatever its nice value (measured: half of both cores): the session's
# autogroup is set to nice 19 too. Each logs to a file; a failure prints its tail.
declare -A background_pid background_log
background() {
  local name=$1 log=$2
  shift 2
  mkdir -p "$(dirname "$log")"
  # shellcheck disable=SC2016  # $@ is the inner shell's
  setsid bash -c '{ echo 19 > /proc/self/autogroup; } 2> /dev/null || true; exec nice -n 19 ionice -c 3 "$@"' background \
    "$@" > "$log" 2>&1 &
  background_pid[$name]=$! background_log[$name]=$log
  echo "== run-all: $name started in the background (at ${SECONDS} s; log $log)"
}
join() {
  local name=$1 waited=$SECONDS
  if ! wait "${background_pid[$name]}"; then
    unset 'background_pid[$name]'
    echo "== run-all: $name failed; the end of ${background_log[$name]}:"
    tail -n 80 "${background_log[$name]}"
    exit 1
  fi
  unset 'background_pid[$name]'
  echo "== run-all: $name done (waited $((SECONDS - waited)) s for it)"
}
finish() {
  local status=$?
  end_stage
  for name in "${!background_pid[@]}"; do kill -- "-${background_pid[$name]}" 2> /dev/null || true; done
  echo "== run-all: exit ${status} after ${SECONDS} s; the stages:"
  printf '%s\n' "${timings[@]}"
}
trap finish EXIT

stage "dependencies"
packaging/install-deps.sh --checks
# The kernel stays a microkernel: size, function length, layering, capability names (tests/check_kernel_shape.py).
stage "kernel shape"
python3 tests/check_kernel_shape_test.py
python3 tests/check_kernel_shape.py
# The arm64 packages (packaging/build-arm64.sh): cross-compiled with Debian's cross toolchain in a debootstrap'ed
# root of their own, smoke-run under qemu-user. Its root is mostly downloads; its build takes idle CPU.
background "arm64 packages" build-arm64/build.log packaging/build-arm64.sh build-arm64

# Unity builds (CMake merges each target's sources, 16 at a time: CMAKE_UNITY_BUILD_BATCH_SIZE in CMakeLists.txt):
# Beast, Asio, JSON and doctest are parsed and instantiated once per batch instead of once per file. Developers' own
# builds stay per-file (fast incremental rebuilds); this keeps the code unity-clean.
stage "normal build"
# Of the benchmarks only the soak (its smoke run below): RCAND_BENCH_IN_ALL, bench/CMakeLists.txt.
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_UNITY_BUILD=ON -DRCAND_BUILD_TESTS=ON \
      -DRCAND_BUILD_BENCH=ON -DRCAND_BENCH_IN_ALL=OFF > /dev/null
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
# The sanitizer build: clang-14 with ASan + UBSan (and libFuzzer coverage), for the suite again and the fuzz targets.
# Any report, in a test or in an rcand it started, fails the suite. Without integration_kernel, _flood and _r2r
# (RCAND_LONG_INTEGRATION_TESTS, tests/integration/CMakeLists.txt): ~8 minutes of running and 2 of building there.
cmake -S . -B build-sanitize -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang-14 \
      -DCMAKE_CXX_COMPILER=clang++-14 -DRCAND_FUZZ=ON -DRCAND_BUILD_TESTS=ON -DRCAND_BUILD_BENCH=OFF -DCMAKE_UNITY_BUILD=ON \
      -DRCAND_LONG_INTEGRATION_TESTS=OFF > /dev/null
background "sanitizer build" build-sanitize/build.log cmake --build build-sanitize

stage "normal build: tests"
# CI runs as root on a machine that reaches Debian's mirror: the clean-root package test must run, never skip.
RCAND_REQUIRE_LIFECYCLE=1 ctest --test-dir build --output-on-failure --timeout 600
# The soak's 20-second smoke run (bench/soak, normal build only): any error fails the suite.
stage "soak smoke run"
bench/soak/run-soak.sh build --smoke
stage "sanitizer build (the rest of it)"
join "sanitizer build"
# One per CPU: nothing else runs now, and one ASan test at a time left a core idle (2026-11-28, this stage on a
# 2-core VM: 210 s two at a time, 81 % of both cores busy; 338 s one at a time in session 12's run).
stage "sanitizer build: tests"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
ctest --test-dir build-sanitize --output-on-failure --timeout 600 --parallel "$(nproc)"

# Every libFuzzer target of that build for a bounded time (RCAND_FUZZ_SECONDS each: 13 targets x 10 s, two at a
# time). The long campaign is tests/fuzz/campaign.sh, outside CI.
stage "fuzzing"
tests/fuzz/run.sh "${RCAND_FUZZ_SECONDS:-10}" build-sanitize
stage "arm64 packages (the rest of them)"
join "arm64 packages"
grep '^== build-arm64' "${background_log[arm64 packages]}"
stage "all passed"
