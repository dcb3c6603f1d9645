#!/usr/bin/env bash
# What isolation: process costs per request (issue 34): a capability route's round trip and a motion command through
# rcand's gate, p50/p99/max, in rcand's process and in the capability's own, and the resident memory of each process.
# Builds what it needs in the build tree (build/ by default); the harness starts and stops every process it runs.
#   bench/run-isolation.sh [build-dir] [samples]
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "${1:-build}")
samples=${2:-2000}
ninja -C "$build" bench_isolation_cost >/dev/null
"$build/bench/bench_isolation_cost" "$samples"
