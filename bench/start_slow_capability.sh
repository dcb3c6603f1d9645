#!/usr/bin/env bash
# Serving before the capabilities are up (issue 32, docs/protocol.md §7.18): exec -> the first 200 from GET /health for
# the bundled sim robot plus one capability whose start() takes 2 s (the fault fixture, tests/plugins/faults, "slow").
# rcand answers before that start returns; a kernel that waited for every capability would take over 2 s.
#   bench/start_slow_capability.sh [build] [runs=5]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
runs=${2:-5}
work=$(mktemp -d)
pid=
cleanup() {
  [ -n "$pid" ] && kill "$pid" 2> /dev/null && wait "$pid" 2> /dev/null
  rm -rf "$work"
}
trap cleanup EXIT
cp config/dev-jwt.secret "$work/"
chmod 600 "$work/dev-jwt.secret"
python3 - "$work" << 'PY'
import sys, yaml
work = sys.argv[1]
config = yaml.safe_load(open("config/sim-rover.rcan.yaml"))
config["rcan_protocol"]["capabilities"].append("org.rcand.test.faulty")
config["runtime"]["state_dir"] = work + "/state"
config["runtime"].setdefault("capabilities", {})["org.rcand.test.faulty"] = {"hook": "start", "fault": "slow", "slow_ms": 2000}
yaml.safe_dump(config, open(work + "/slow.rcan.yaml", "w"))
PY
for i in $(seq "$runs"); do
  port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  t0=$(date +%s%3N)
  "$build/kernel/rcand" --config "$work/slow.rcan.yaml" --plugin-path "$build/plugins" \
    --plugin-path "$build/test-plugins/faults" --port "$port" > "$work/out" 2> "$work/err" &
  pid=$!
  until curl -fsS -o /dev/null --max-time 1 "http://127.0.0.1:$port/health" 2> /dev/null; do
    kill -0 "$pid" 2> /dev/null || { cat "$work/err" >&2; exit 1; }
    sleep 0.002
  done
  echo "run $i: exec -> /health 200 in $(($(date +%s%3N) - t0)) ms"
  kill "$pid"
  wait "$pid" 2> /dev/null || true
  pid=
done
