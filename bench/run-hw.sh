#!/usr/bin/env bash
# Hardware-driver benchmarks (issue 17) on the fake buses: halt() latency of the PCA9685 (fake bus), Dynamixel (pty
# emulator at 1 Mbps wire timing), GPIO (fake chip) and Arduino bridge (pty emulator of the firmware, answering and
# hung) drivers, and a 100 Hz sync write/read loop for 6 servos.
# Needs a built tree (build/ by default).
#   bench/run-hw.sh [build-dir] [samples] [loop-cycles]
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "${1:-build}")
"$build/bench/bench_hw_halt" "${2:-500}" "${3:-1000}"
