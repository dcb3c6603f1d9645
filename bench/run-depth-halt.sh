#!/usr/bin/env bash
# Depth obstacle -> motors halted (issue 15): the bundled sim robot (synthetic depth, safety.obstacle_stop_cm) with an
# object placed in front of a moving nav job and of a teleop move; p50/p90/p99/max from the sim drive's timeline.
# Needs a built tree (build/ by default).
#   bench/run-depth-halt.sh [build-dir] [samples]
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "${1:-build}")
samples=${2:-300}
port=18620
token=rcand-dev-owner
work=$(mktemp -d)
trap 'kill $pid 2>/dev/null || true; wait $pid 2>/dev/null || true; rm -rf "$work"' EXIT

# The bundled sim robot as it is (depth and the obstacle minimum are on), rate limits off (the benchmark polls the
# drive's timeline as fast as it can), its own state directory.
sed -e '/^runtime:/a\  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}' \
    -e "s|^  state_dir: .*|  state_dir: $work/state|" \
  config/sim-rover.rcan.yaml >"$work/robot.rcan.yaml"
cp config/dev-jwt.secret "$work/"
chmod 600 "$work/dev-jwt.secret"
"$build/kernel/rcand" --config "$work/robot.rcan.yaml" --plugin-path "$build/plugins" --port $port >"$work/out" 2>"$work/err" &
pid=$!
until grep -q "listening on" "$work/out"; do kill -0 $pid; sleep 0.05; done

"$build/bench/bench_depth_halt" $port $token "$samples"
