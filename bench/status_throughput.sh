#!/usr/bin/env bash
# GET /api/status and GET /health throughput (issue 14 item 6): wrk -t1 -c64 -d10s against the bundled sim robot,
# authenticated as the dev owner, rate limits off (this measures the server and the status snapshot, not the
# limiter, which would answer 429). Needs a built tree and wrk.
#   bench/status_throughput.sh [build-dir]
#   RCAND=path/to/rcand PLUGINS=path/to/plugin-dir bench/status_throughput.sh   (e.g. an older build kept aside)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
rcand=${RCAND:-$build/kernel/rcand}
plugins=${PLUGINS:-$build/plugins}
duration=${DURATION:-10s}
command -v wrk >/dev/null || { echo "needs wrk: apt-get install --no-install-recommends wrk" >&2; exit 2; }
port=${PORT:-18610}
token=rcand-dev-owner
work=$(mktemp -d)
pid=
trap '[ -n "$pid" ] && { kill $pid 2>/dev/null || true; wait $pid 2>/dev/null || true; }; rm -rf "$work"' EXIT

sed '/^runtime:/a\  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}' config/sim-rover.rcan.yaml >"$work/robot.rcan.yaml"
# The sim config keeps its state dir in build/; a scratch one lets this run beside a test run or another rcand.
sed -i "s|^\(\s*state_dir:\).*|\1 $work/state|" "$work/robot.rcan.yaml"
cp config/dev-jwt.secret "$work/"
chmod 600 "$work/dev-jwt.secret"
"$rcand" --config "$work/robot.rcan.yaml" --plugin-path "$plugins" --port "$port" >"$work/out" 2>"$work/err" &
pid=$!
until grep -q "listening on" "$work/out"; do
  kill -0 $pid 2>/dev/null || { cat "$work/err" >&2; exit 1; }
  sleep 0.05
done
curl -fsS -H "Authorization: Bearer $token" "http://127.0.0.1:$port/api/status" >/dev/null

run() {  # label, path, auth header or empty
  local label=$1 path=$2
  shift 2
  echo "== $label (wrk -t1 -c64 -d$duration) =="
  wrk -t1 -c64 -d"$duration" "$@" "http://127.0.0.1:$port$path" | grep -E "Requests/sec|Latency|requests in|Non-2xx"
}
run "GET /api/status" /api/status -H "Authorization: Bearer $token"
run "GET /health" /health
