#!/usr/bin/env bash
# Dashboard first paint (issue 18): rcand on the bundled simulated robot (any free port), the page loaded cold 50
# times in headless Chromium. Needs a built tree and the dashboard test's node folder (ctest -R integration_dashboard
# makes it: <build>/tests/dashboard-node with playwright-core).
#   bench/run-dashboard.sh [build-dir] [loads]
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "${1:-build}")
node_dir="$build/tests/dashboard-node"
[ -d "$node_dir/node_modules/playwright-core" ] || { echo "run: ctest --test-dir $build -R integration_dashboard first" >&2; exit 1; }
cp bench/dashboard_first_paint.mjs "$node_dir/"
out=$(mktemp)
"$build/kernel/rcand" --config config/sim-rover.rcan.yaml --port 0 > "$out" 2>/dev/null &
rcand=$!
trap 'kill $rcand 2>/dev/null; wait $rcand 2>/dev/null; rm -f "$out"' EXIT
until grep -q "listening on" "$out"; do kill -0 $rcand || exit 1; sleep 0.05; done
base=$(grep -o "http://[0-9.:]*" "$out" | head -1)
node "$node_dir/dashboard_first_paint.mjs" "$base" "${2:-50}"
