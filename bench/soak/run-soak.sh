#!/usr/bin/env bash
# Soak benchmark (issue 8): two sim robots under a paced mixed load (status, teleop, nav, stop/clear, swarm broadcast
# stops), per-interval errors, p50/p99/max per endpoint and resident memory. Needs a tree built with
# -DRCAND_BUILD_BENCH=ON.
#   bench/soak/run-soak.sh [build-dir] [--minutes N | --smoke]     (default: build, 10 minutes)
set -euo pipefail
cd "$(dirname "$0")/../.."
build=build
if [[ $# -gt 0 && $1 != --* ]]; then build=$1; shift; fi
driver="$build/bench/bench_soak"
[[ -x $driver ]] || { echo "no $driver: configure with -DRCAND_BUILD_BENCH=ON and build target bench_soak" >&2; exit 2; }
echo "machine: $(nproc) cores, load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
status=0
"$driver" "$@" || status=$?
echo "load average at end: $(cut -d' ' -f1-3 /proc/loadavg)"
exit $status
