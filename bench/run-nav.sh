#!/usr/bin/env bash
# Nav benchmarks (issue 3): POST /api/stop received -> motors at zero during a running nav job, and commanded vs
# actual turn/drive durations, both read from the sim drive's timeline. Needs a built tree (build/ by default).
#   bench/run-nav.sh [build-dir] [samples]
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "${1:-build}")
samples=${2:-200}
port=18610
token=rcand-dev-owner
work=$(mktemp -d)
trap 'kill $pid 2>/dev/null || true; wait $pid 2>/dev/null || true; rm -rf "$work"' EXIT

# The bundled sim robot with nav declared (its physics block already has the §10.2 fields), rate limits off (the
# benchmark polls as fast as it can).
sed -e 's/capabilities: \[status, teleop, com.acme.gripper\]/capabilities: [status, teleop, nav, com.acme.gripper]/' \
    -e '/^runtime:/a\  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}' \
  config/sim-rover.rcan.yaml >"$work/robot.rcan.yaml"
cp config/dev-jwt.secret "$work/"
chmod 600 "$work/dev-jwt.secret"
"$build/kernel/rcand" --config "$work/robot.rcan.yaml" --plugin-path "$build/plugins" --port $port >"$work/out" 2>"$work/err" &
pid=$!
until grep -q "listening on" "$work/out"; do kill -0 $pid; sleep 0.05; done

"$build/bench/bench_nav" $port $token "$samples"
