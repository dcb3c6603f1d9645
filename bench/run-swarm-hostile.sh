#!/usr/bin/env bash
# 100 concurrent broadcast stops to bravo plus nine hostile peers while the machine is loaded (issue 28 #3).
#   bench/run-swarm-hostile.sh [build-dir] [runs] [concurrent] [load]
# Each run is a fresh bench_broadcast_stop_hostile process (origin, bravo and the peers started anew) with `concurrent`
# stops in one round. The load stands in for a build running on the machine: `load` CPU hogs at nice 0, like the
# compilers of a `cmake --build -j2` (stress-ng --cpu N --cpu-method matrixprod, Debian package stress-ng), started
# before the first run and stopped after the last. load 0: an idle machine.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
runs=${2:-12}
concurrent=${3:-100}
load=${4:-$(nproc)}
command -v stress-ng >/dev/null || { echo "needs stress-ng: apt-get install --no-install-recommends stress-ng" >&2; exit 2; }
ulimit -n 8192 2>/dev/null || true
work=$(mktemp -d)
stress_pid=
cleanup() {
  if [ -n "$stress_pid" ]; then kill "$stress_pid" 2>/dev/null || true; wait "$stress_pid" 2>/dev/null || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
if [ "$load" -gt 0 ]; then
  stress-ng --cpu "$load" --cpu-method matrixprod --quiet &
  stress_pid=$!
  sleep 1
fi
echo "load: ${load} x stress-ng --cpu-method matrixprod at nice 0 on $(nproc) cores; $runs runs of $concurrent concurrent stops"
status=0
for run in $(seq 1 "$runs"); do
  if ! "$build/bench/bench_broadcast_stop_hostile" "$concurrent" 1 "$work/raw" >"$work/run$run" 2>"$work/err$run"; then status=1; fi
  grep -E "^all|per-node|RSS" "$work/run$run" | sed "s/^/run $run: /"
  grep -h "unexpected answer" "$work/err$run" | head -3 | sed "s/^/run $run: /" || true
done
# Every answer of every run, pooled.
cat "$work"/run* | grep -h "^all" >"$work/summaries" || true
python3 - "$work/raw" "$work/summaries" <<'EOF'
import re, sys
rows = [tuple(map(float, line.split())) for line in open(sys.argv[1]) if line.strip()]
def pct(values, p):
    values = sorted(values)
    return values[int(p * (len(values) - 1))] if values else 0.0
for i, what in ((0, "answer at the client"), (1, "rcand's latest per-node latency"), (2, "stop handler reached after")):
    v = [r[i] for r in rows if len(r) > i]
    if v: print(f"{what} ms over {len(v)} answers: p50 {pct(v, .5):.1f}  p99 {pct(v, .99):.1f}  p100 {pct(v, 1):.1f}")
text = open(sys.argv[2]).read()
total = lambda key: sum(int(m) for m in re.findall(key + r": (\d+)", text))
print(f"answers over 500 ms: {sum(1 for r in rows if r[0] >= 500)}  unexpected answers: {total('unexpected')}  "
      f"reports with bravo ok: {total('bravo ok')} of {len(rows)}")
EOF
exit $status
