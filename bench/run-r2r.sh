#!/usr/bin/env bash
# R2R benchmarks (issue 7): round trips and throughput per transport between a peer and a robot, and auction time
# for 3, 10 and 50 bidders (target: decided within the bid window + 50 ms).
#   bench/run-r2r.sh [build-dir]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
ulimit -n 8192 2>/dev/null || true
"$build/bench/bench_r2r" transport 2000
for n in 3 10 50; do
  "$build/bench/bench_r2r" auction $n 10
done
