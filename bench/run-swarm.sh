#!/usr/bin/env bash
# Swarm benchmarks (issue 4): broadcast stop to 16 and 64 rcand processes, with and without one unreachable node;
# then (issue 13) 100 concurrent broadcast stops while one peer streams an endless answer.
#   bench/run-swarm.sh [build-dir]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
ulimit -n 8192 2>/dev/null || true
for n in 16 64; do
  "$build/bench/bench_swarm_stop" $n 200
  "$build/bench/bench_swarm_stop" $n 20 --unreachable
done
"$build/bench/bench_broadcast_stop_streaming" 100 10
