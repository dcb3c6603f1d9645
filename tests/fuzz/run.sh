#!/usr/bin/env bash
# Runs every libFuzzer target of a fuzz build for a bounded time and prints, per target: executions, coverage
# (cov: edges, ft: features), corpus size, crashes. Exits non-zero on any crash, sanitizer report or leak.
#
#   tests/fuzz/run.sh SECONDS_PER_TARGET [BUILD_DIR]     BUILD_DIR defaults to build-sanitize (what CI builds)
#
# The build: cmake -S . -B build-sanitize -G Ninja -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
#            -DRCAND_FUZZ=ON && cmake --build build-sanitize --target rcand_fuzz_targets
# The checked-in seeds (tests/fuzz/corpus/<target>/) are only read; what a run finds goes to a scratch corpus, kept
# when RCAND_FUZZ_WORK names a directory. A crashing input is copied to BUILD_DIR/fuzz-artifacts/ with the command
# that replays it.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
seconds="${1:?usage: tests/fuzz/run.sh SECONDS_PER_TARGET [BUILD_DIR]}"
build="${2:-$root/build-sanitize}"
case "$build" in /*) ;; *) build="$root/$build" ;; esac
bin_dir="$build/tests/fuzz"

targets=()
for bin in "$bin_dir"/fuzz_*; do [ -x "$bin" ] && [ -f "$bin" ] && targets+=("$(basename "$bin")"); done
if [ ${#targets[@]} -eq 0 ]; then
  echo "run.sh: no fuzz targets in $bin_dir (configure with -DRCAND_FUZZ=ON and build rcand_fuzz_targets)" >&2
  exit 2
fi

if [ -n "${RCAND_FUZZ_WORK:-}" ]; then
  work="$RCAND_FUZZ_WORK"; mkdir -p "$work"
else
  work="$(mktemp -d /tmp/rcand-fuzz.XXXXXX)"; trap 'rm -rf "$work"' EXIT
fi

# A report anywhere ends the run with a non-zero status; leaks count.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export ASAN_SYMBOLIZER_PATH="${ASAN_SYMBOLIZER_PATH:-$(command -v llvm-symbolizer-14 || command -v llvm-symbolizer || true)}"

# target_options NAME: its dictionary and flags.
source "$here/target_options.sh"

# What libFuzzer saves when an input crashes, leaks, hangs or runs out of memory.
artifacts() { find "$1" -maxdepth 1 \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' -o -name 'oom-*' \); }

# One target: its log, its row of the table, and its crash count in $work/<name>/.
fuzz_one() {
  local bin="$1" name="${1#fuzz_}" status=0
  local seeds="$here/corpus/$name" log="$work/$name/log"
  mkdir -p "$work/$name/corpus"
  local args=(-max_total_time="$seconds" -timeout=20 -rss_limit_mb=2048 -print_final_stats=1
              -artifact_prefix="$work/$name/")
  mapfile -t -O "${#args[@]}" args < <(target_options "$name")
  "$bin_dir/$bin" "${args[@]}" "$work/$name/corpus" "$seeds" > "$log" 2>&1 || status=$?
  local execs rate cov ft corpus crashes
  # A crashed target may print no stats: a missing figure shows as "?".
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1 || true)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1 || true)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || true)
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || true)
  corpus=$(find "$work/$name/corpus" "$seeds" -type f | wc -l)
  crashes=$(artifacts "$work/$name" | wc -l)
  if [ "$status" -ne 0 ] && [ "$crashes" -eq 0 ]; then crashes=1; fi
  printf '%-16s %6s %12s %8s %7s %7s %6s %7s\n' "$name" "$seconds" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" \
         "$corpus" "$crashes" > "$work/$name/row"
  echo "$status $crashes" > "$work/$name/result"
}

# The targets are independent and single-threaded: RCAND_FUZZ_JOBS of them (default: one per CPU) run at once, so
# the wall time is about SECONDS x targets / jobs.
jobs="${RCAND_FUZZ_JOBS:-$(nproc)}"
for bin in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n || true; done
  fuzz_one "$bin" &
done
wait

failed=0
printf '%-16s %6s %12s %8s %7s %7s %6s %7s\n' target seconds executions exec/s cov ft corpus crashes
for bin in "${targets[@]}"; do
  name="${bin#fuzz_}"
  status=1 crashes=1
  if [ -f "$work/$name/result" ]; then cat "$work/$name/row"; read -r status crashes < "$work/$name/result"; fi
  if [ "$crashes" -ne 0 ]; then
    failed=1
    echo "---- $name failed (exit $status); the end of its log:" >&2
    tail -60 "$work/$name/log" >&2
    mkdir -p "$build/fuzz-artifacts"
    for input in $(artifacts "$work/$name"); do
      cp "$input" "$build/fuzz-artifacts/$name-$(basename "$input")"
      echo "---- input saved: $build/fuzz-artifacts/$name-$(basename "$input")" \
           "(replay: $bin_dir/$bin $build/fuzz-artifacts/$name-$(basename "$input"))" >&2
    done
  fi
done
exit "$failed"
