#!/usr/bin/env bash
# Issue 32, the stop's answer path: GET /health and POST /api/stop (a clear between) in the same run on one kept-alive
# connection, against the bundled sim robot (its three drivers, rate limits off):
#   1. the C++ client (bench_stop_latency ... health), with the stop's excess over /health against the targets;
#   2. the Python stdlib client (bench/stop_vs_health.py), the same client the reference runtime is measured with.
# With --reference DIR (a checkout of craigm26/OpenCastor, or its bare mirror: then archived into a temp dir), the
# Python client runs against its API gateway too: castor.api with its config/examples/minimal.rcan.yaml (a `mock`
# driver, which v3.0.1 does not know: it runs without one, so its stop halts nothing), started by
# bench/reference_gateway.py on Debian 12's FastAPI and uvicorn (it says which gaps to a pip install it bridges).
# With --rest, the C++ client runs a second time with the robot at rest when each round starts (health-rest: 20 ms
# apart, the previous clear's latch records written).
#   bench/run-stop-path.sh [--build DIR] [--samples N] [--rest] [--reference DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
build=build samples=1000 reference="" rest=""
while [ $# -gt 0 ]; do
  case $1 in
    --build) build=$2; shift 2 ;;
    --samples) samples=$2; shift 2 ;;
    --reference) reference=$2; shift 2 ;;
    --rest) rest=1; shift ;;
    *) echo "usage: $0 [--build DIR] [--samples N] [--rest] [--reference DIR]" >&2; exit 2 ;;
  esac
done
token=rcand-dev-owner
work=$(mktemp -d)
pids=()
trap 'for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; wait "$p" 2>/dev/null || true; done; rm -rf "$work"' EXIT

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }

echo "VM: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs); load: $(cut -d' ' -f1-3 /proc/loadavg)"
port=$(free_port)
sed -e '/^runtime:/a\  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}' \
    -e "s#state_dir: ../build/state#state_dir: $work/state#" config/sim-rover.rcan.yaml >"$work/robot.rcan.yaml"
cp config/dev-jwt.secret "$work/"
chmod 600 "$work/dev-jwt.secret"
"$build/kernel/rcand" --config "$work/robot.rcan.yaml" --plugin-path "$build/plugins" --port "$port" >"$work/out" 2>"$work/err" &
pids+=($!)
until grep -qs "listening on" "$work/out"; do kill -0 "${pids[0]}"; sleep 0.05; done

echo "== rcand, the C++ client (bench_stop_latency $samples health) =="
"$build/bench/bench_stop_latency" "$port" "$token" "$samples" health
if [ -n "$rest" ]; then
  echo "== rcand, the C++ client, the robot at rest before each round (bench_stop_latency $samples health-rest) =="
  "$build/bench/bench_stop_latency" "$port" "$token" "$samples" health-rest
fi
echo "== rcand, the Python stdlib client =="
python3 bench/stop_vs_health.py "$port" "$token" "$samples"

[ -n "$reference" ] || exit 0
echo "== the reference runtime ($reference), the Python stdlib client =="
src=$reference
if [ ! -e "$reference/castor/api.py" ]; then  # a bare mirror: its HEAD into a temp dir
  src=$work/reference
  mkdir -p "$src"
  git --git-dir="$reference" archive HEAD | tar -x -C "$src"
fi
# Its server runs on the first Python with FastAPI and uvicorn (Debian 12: python3-fastapi python3-uvicorn
# python3-uvloop python3-httptools, and the gateway's other imports); the client stays the same python3 as above.
server_python=""
for candidate in python3 /usr/bin/python3; do
  if "$candidate" -c 'import fastapi, uvicorn' 2>/dev/null; then server_python=$candidate; break; fi
done
if [ -z "$server_python" ]; then
  echo "cannot run the reference runtime here: no Python with fastapi and uvicorn (apt-get install python3-fastapi"
  echo "python3-uvicorn python3-uvloop python3-httptools python3-numpy python3-jwt python3-dotenv python3-httpx"
  echo "python3-multipart python3-cryptography python3-requests python3-serial, or pip install -e $src)"
  exit 0
fi
rport=$(free_port)
ref_token=bench-reference-token
(cd "$src" && OPENCASTOR_API_TOKEN=$ref_token OPENCASTOR_CONFIG=config/examples/minimal.rcan.yaml \
  ANTHROPIC_API_KEY=${ANTHROPIC_API_KEY:-unused-by-this-bench} OPENCASTOR_MEMORY_DIR="$work/reference-memory" \
  "$server_python" "$root/bench/reference_gateway.py" "$src" "$rport") >"$work/ref.out" 2>&1 &
pids+=($!)
for _ in $(seq 300); do
  python3 -c "import http.client,sys; c=http.client.HTTPConnection('127.0.0.1',$rport,timeout=1); c.request('GET','/health'); sys.exit(c.getresponse().status!=200)" 2>/dev/null && break
  kill -0 "${pids[-1]}" 2>/dev/null || { echo "the reference gateway exited:"; tail -n 20 "$work/ref.out"; exit 1; }
  sleep 0.1
done
grep '^reference_gateway:' "$work/ref.out" || true
grep -m1 'driver protocol' "$work/ref.out" || true
python3 bench/stop_vs_health.py "$rport" "$ref_token" "$samples"
