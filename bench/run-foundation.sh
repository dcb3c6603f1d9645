#!/usr/bin/env bash
# Foundation benchmarks (issue "Foundation"): GET /api/status throughput with wrk, POST /api/stop latency while
# other clients saturate GET /api/status, and idle resident memory. Needs a built tree (build/) and wrk.
#   bench/run-foundation.sh [build-dir]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
command -v wrk >/dev/null || { echo "needs wrk: apt-get install --no-install-recommends wrk" >&2; exit 2; }
port=18600
token=rcand-dev-owner
work=$(mktemp -d)
trap 'kill $pid 2>/dev/null || true; wait $pid 2>/dev/null || true; rm -rf "$work"' EXIT

# The bundled sim robot, its rate limits off: this measures the server, not the limiter (which would answer 429).
sed '/^runtime:/a\  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}' config/sim-rover.rcan.yaml >"$work/robot.rcan.yaml"
cp config/dev-jwt.secret "$work/"
chmod 600 "$work/dev-jwt.secret"
"$build/kernel/rcand" --config "$work/robot.rcan.yaml" --plugin-path "$build/plugins" --port $port >"$work/out" 2>"$work/err" &
pid=$!
until grep -q "listening on" "$work/out"; do kill -0 $pid; sleep 0.05; done

rss_kb() { awk '/VmRSS/ {print $2}' /proc/$pid/status; }
echo "idle RSS after start: $(rss_kb) kB"

echo "== GET /api/status throughput (wrk -t1 -c64 -d10s) =="
wrk -t1 -c64 -d10s -H "Authorization: Bearer $token" "http://127.0.0.1:$port/api/status" | grep -E "Requests/sec|Latency|requests in"

echo "== POST /api/stop latency while wrk saturates GET /api/status (the owner, 32 connections) =="
wrk -t1 -c32 -d60s -H "Authorization: Bearer $token" "http://127.0.0.1:$port/api/status" >"$work/wrk" &
wrk_pid=$!
sleep 1
echo "-- a guest's stops, each on a fresh connection (issue 13: p99 <= 1 ms) --"
"$build/bench/bench_stop_latency" $port rcand-dev-guest 3000 fresh $token
echo "-- the same stops on one kept-alive connection --"
"$build/bench/bench_stop_latency" $port rcand-dev-guest 3000 keepalive $token
kill -INT $wrk_pid 2>/dev/null || true; wait $wrk_pid 2>/dev/null || true
grep -E "Requests/sec" "$work/wrk" | sed 's/^/status load: /' || true
if chrt -f 20 true 2>/dev/null; then
  # The same, the stop client real-time: what rcand adds when the client's own CPU is not the saturated one (an
  # operator's laptop or the e-stop pendant is another machine).
  wrk -t1 -c32 -d30s -H "Authorization: Bearer $token" "http://127.0.0.1:$port/api/status" >"$work/wrk" &
  wrk_pid=$!
  sleep 1
  echo "-- a guest's stops, each on a fresh connection, the stop client real-time (chrt -f 20) --"
  chrt -f 20 "$build/bench/bench_stop_latency" $port rcand-dev-guest 3000 fresh $token
  kill -INT $wrk_pid 2>/dev/null || true; wait $wrk_pid 2>/dev/null || true
fi

echo "== POST /api/stop latency, idle robot =="
"$build/bench/bench_stop_latency" $port $token 3000
echo "idle RSS after the runs: $(rss_kb) kB"

echo "== POST /api/stop during a 10,000-connection flood and a slow-loris at the limit =="
ulimit -n 65536 2>/dev/null || true
"$build/bench/bench_stop_under_flood" 10000
