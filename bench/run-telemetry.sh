#!/usr/bin/env bash
# Telemetry benchmark (issue 18): an rcand with the sim robot and 50 WS /ws/telemetry clients at 5 Hz for 30 s
# (frame-interval jitter p50/p99/max), then 30 e-stops each pushed to all of them (POST sent -> last client read it).
# Needs a built tree (build/ by default). Extra arguments go to bench_telemetry (--clients, --seconds, --trials).
#   bench/run-telemetry.sh [build-dir] [bench_telemetry options]
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "${1:-build}")
shift || true
"$build/bench/bench_telemetry" "$@"
