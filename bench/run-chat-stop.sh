#!/usr/bin/env bash
# POST /api/stop p99 on a real rcand while chat's brains are busy (issue 16): four 2-second model calls and one hung
# one in flight against a scripted OpenAI-compatible server on loopback, side by side with the same stop when idle.
# bench_chat_stop starts rcand itself (the integration harness). Needs a built tree with RCAND_BUILD_TESTS and
# RCAND_BUILD_BENCH (build/ by default).
#   bench/run-chat-stop.sh [build-dir] [samples]
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "${1:-build}")
"$build/bench/bench_chat_stop" "${2:-200}"
