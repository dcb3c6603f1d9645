#!/usr/bin/env bash
# The long fuzzing campaign, outside CI: each named target of a fuzz build runs until RUNS executions or SECONDS,
# whichever comes first, at the lowest CPU priority and one campaign process at a time on the machine (flock on
# $RCAND_FUZZ_LOCK, default /tmp/rcand-fuzz.lock: a second campaign waits instead of halving both; on an idle machine
# give each of N campaigns a lock of its own to run N targets at once), then its new inputs are minimized into the
# checked-in corpus. Prints, and appends to WORK/results.tsv, per target: executions, exec/s, cov (edges), ft
# (features), corpus files before and after the merge, crashes.
#
#   tests/fuzz/campaign.sh [-n RUNS] [-t SECONDS] BUILD_DIR TARGET...     (TARGET without the fuzz_ prefix)
#
# Do not pause a running campaign (SIGSTOP) to measure something else: libFuzzer's -timeout and -max_total_time
# count wall time, so a unit stopped for over 20 s is reported as a timeout (seen: a 51 ms input, 2026-11-28).
# RUNS defaults to 10,000,000, SECONDS to 3600. WORK is $RCAND_FUZZ_WORK, default /tmp/rcand-fuzz-campaign; each
# target's scratch corpus and log stay there (a later run continues from them). A crash, leak, timeout or
# out-of-memory input stays in WORK/<target>/ and is reported; the merge then keeps only what reproduces cleanly.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
runs=10000000
seconds=3600
while getopts "n:t:" option; do
  case "$option" in
    n) runs="$OPTARG" ;;
    t) seconds="$OPTARG" ;;
    *) exit 2 ;;
  esac
done
shift $((OPTIND - 1))
build="${1:?usage: tests/fuzz/campaign.sh [-n RUNS] [-t SECONDS] BUILD_DIR TARGET...}"
shift
case "$build" in /*) ;; *) build="$root/$build" ;; esac
work="${RCAND_FUZZ_WORK:-/tmp/rcand-fuzz-campaign}"
mkdir -p "$work"
lock="${RCAND_FUZZ_LOCK:-/tmp/rcand-fuzz.lock}"

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export ASAN_SYMBOLIZER_PATH="${ASAN_SYMBOLIZER_PATH:-$(command -v llvm-symbolizer-14 || command -v llvm-symbolizer || true)}"

source "$here/target_options.sh"

failed=0
for name in "$@"; do
  bin="$build/tests/fuzz/fuzz_$name"
  seeds="$here/corpus/$name"
  [ -x "$bin" ] || { echo "campaign: no $bin" >&2; exit 2; }
  mkdir -p "$work/$name/corpus"
  args=(-runs="$runs" -max_total_time="$seconds" -timeout=20 -rss_limit_mb=2048 -print_final_stats=1
        -artifact_prefix="$work/$name/")
  mapfile -t -O "${#args[@]}" args < <(target_options "$name")
  log="$work/$name/log"
  status=0
  flock "$lock" nice -n 19 "$bin" "${args[@]}" "$work/$name/corpus" "$seeds" > "$log" 2>&1 || status=$?
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1 || true)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1 || true)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || true)
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || true)
  crashes=$(find "$work/$name" -maxdepth 1 \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' -o -name 'oom-*' \) | wc -l)
  if [ "$status" -ne 0 ] && [ "$crashes" -eq 0 ]; then crashes=1; fi
  before=$(find "$seeds" -type f | wc -l)
  # Only inputs that add coverage to the checked-in corpus join it; the named seeds stay.
  flock "$lock" nice -n 19 "$bin" -merge=1 -timeout=20 -rss_limit_mb=2048 "$seeds" "$work/$name/corpus" \
    > "$work/$name/merge.log" 2>&1 || true
  after=$(find "$seeds" -type f | wc -l)
  row="$name	${execs:-?}	${rate:-?}	${cov:-?}	${ft:-?}	$before	$after	$crashes	$(date -u +%FT%TZ)"
  echo "$row" | tee -a "$work/results.tsv"
  if [ "$crashes" -ne 0 ]; then
    failed=1
    echo "---- $name: exit $status; inputs kept in $work/$name/; the end of its log:" >&2
    tail -40 "$log" >&2
  fi
done
exit "$failed"
