#!/usr/bin/env bash
# The bundled sim robot's start time and idle memory (issue 32), with and without the camera (the `camera` block and
# `vision` taken out of config/sim-rover.rcan.yaml):
#   start: exec -> the first 200 from GET /health (polled every 2 ms, client clock), the median and range of N runs;
#   memory: 4 s after start, VmRSS and its anonymous / file-backed parts (RssAnon, RssFile from /proc/PID/status),
#     and the largest parts by mapping (Rss summed per file, or [heap], [stack], [anon], from /proc/PID/smaps);
#   CPU at rest: rcand's utime + stime over the next 10 s, in % of one core (nobody connected).
#   bench/start_rss.sh [build] [runs=10]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
runs=${2:-10}
work=$(mktemp -d)
pid=
cleanup() {
  [ -n "$pid" ] && kill "$pid" 2> /dev/null && wait "$pid" 2> /dev/null
  rm -rf "$work"
}
trap cleanup EXIT
cp config/dev-jwt.secret "$work/"
cp config/sim-rover.rcan.yaml "$work/camera.rcan.yaml"
# Without a camera: the camera block (to the next top-level key) and vision from the capability list.
awk '/^camera:/ {skip = 1; next} skip && /^[a-z]/ {skip = 0} !skip' config/sim-rover.rcan.yaml |
  sed 's/capabilities: \[status, teleop, nav, vision, /capabilities: [status, teleop, nav, /' > "$work/plain.rcan.yaml"
sed -i "s|^\(\s*state_dir:\).*|\1 $work/state|" "$work/camera.rcan.yaml" "$work/plain.rcan.yaml"
chmod 600 "$work/dev-jwt.secret"

free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
now_ms() { date +%s%3N; }

# One start: sets elapsed to the ms from exec to the first 200 from /health; leaves rcand running as $pid.
start_once() {
  local config=$1 port
  port=$(free_port)
  local t0
  t0=$(now_ms)
  "$build/kernel/rcand" --config "$work/$config" --plugin-path "$build/plugins" --port "$port" > "$work/out" 2> "$work/err" &
  pid=$!
  until curl -fsS -o /dev/null --max-time 1 "http://127.0.0.1:$port/health" 2> /dev/null; do
    kill -0 "$pid" 2> /dev/null || { cat "$work/err" >&2; exit 1; }
    sleep 0.002
  done
  elapsed=$(($(now_ms) - t0))
}
stop_rcand() {
  kill "$pid"
  wait "$pid" 2> /dev/null || true
  pid=
}

for config in camera plain; do
  times=()
  for ((i = 0; i < runs; i++)); do
    start_once $config.rcan.yaml
    times+=("$elapsed")
    if ((i == runs - 1)); then
      sleep 4
      mem=$(awk '/^(VmRSS|RssAnon|RssFile):/ {printf "%s %.1f MB  ", $1, $2 / 1024}' /proc/$pid/status)
      maps=$(grep -c 'opencv\|avcodec\|gst\|gdal' /proc/$pid/maps || true)
      parts=$(awk '/^[0-9a-f]+-[0-9a-f]+ / {n = split($6, p, "/"); name = $6 == "" ? "[anon]" : p[n]}
                   /^Rss:/ {rss[name] += $2}
                   END {for (k in rss) if (rss[k] >= 100) printf "%d %s\n", rss[k], k}' /proc/$pid/smaps |
        sort -rn | head -12 | awk '{printf "%s%s %.1f", (NR > 1 ? ", " : ""), $2, $1 / 1024} END {print ""}')
      ticks0=$(awk '{print $14 + $15}' /proc/$pid/stat)
      sleep 10
      ticks1=$(awk '{print $14 + $15}' /proc/$pid/stat)
      cpu=$(awk -v t="$((ticks1 - ticks0))" -v hz="$(getconf CLK_TCK)" 'BEGIN {printf "%.2f", 100 * t / hz / 10}')
    fi
    stop_rcand
  done
  sorted=$(printf '%s\n' "${times[@]}" | sort -n)
  median=$(echo "$sorted" | awk '{a[NR] = $1} END {print (NR % 2 ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2)}')
  echo "$config: exec -> /health 200: median ${median} ms, range $(echo "$sorted" | head -1)-$(echo "$sorted" | tail -1) ms ($runs runs)"
  echo "$config: 4 s after start: $mem (maps of opencv/avcodec/gst/gdal: $maps); CPU at rest: ${cpu} % of a core"
  echo "$config: the largest parts (MB): $parts"
done
