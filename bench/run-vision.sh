#!/usr/bin/env bash
# Vision benchmark (issue 15): an rcand with the bundled synthetic camera (640x480 at 30 fps) streaming MJPEG to 20
# local viewers for 20 s; prints per-viewer fps, rcand's CPU, capture -> client latency and stops while streaming.
# Needs a built tree (build/ by default). Extra arguments go to bench_vision (--viewers, --seconds, --width, ...).
#   bench/run-vision.sh [build-dir] [bench_vision options]
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "${1:-build}")
shift || true
"$build/bench/bench_vision" "$@"
