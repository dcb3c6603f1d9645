#!/usr/bin/env bash
# rcand's resident memory across development plugin reloads (issue 28 item 6): the bundled sim robot with
# runtime.plugins.allow_reload, plugin PLUGIN (default org.rcand.vision) reloaded N times (default 100), VmRSS read
# from /proc before the first reload and after the last. Each reload keeps the old image mapped for good, so rcand
# refuses reloads past PluginHost::kMaxReopens (409 RELOAD_LIMIT); the answers are counted by status.
#   bench/reload_rss.sh [build-dir]
#   RCAND=path/to/rcand PLUGINS=path/to/plugin-dir bench/reload_rss.sh   (e.g. an older build kept aside)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
rcand=${RCAND:-$build/kernel/rcand}
plugins=${PLUGINS:-$build/plugins}
plugin=${PLUGIN:-org.rcand.vision}
reloads=${N:-100}
port=${PORT:-18620}
token=rcand-dev-owner
work=$(mktemp -d)
pid=
trap '[ -n "$pid" ] && { kill $pid 2>/dev/null || true; wait $pid 2>/dev/null || true; }; rm -rf "$work"' EXIT

sed '/^runtime:/a\  plugins: {allow_reload: true}\n  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}' \
  config/sim-rover.rcan.yaml >"$work/robot.rcan.yaml"
sed -i "s|^\(\s*state_dir:\).*|\1 $work/state|" "$work/robot.rcan.yaml"
cp config/dev-jwt.secret "$work/"
chmod 600 "$work/dev-jwt.secret"
"$rcand" --config "$work/robot.rcan.yaml" --plugin-path "$plugins" --port "$port" >"$work/out" 2>"$work/err" &
pid=$!
until grep -q "listening on" "$work/out"; do
  kill -0 $pid 2>/dev/null || { cat "$work/err" >&2; exit 1; }
  sleep 0.05
done
rss() { awk '/^VmRSS/ {print $2}' "/proc/$pid/status"; }
curl -fsS -H "Authorization: Bearer $token" "http://127.0.0.1:$port/api/status" >/dev/null
before=$(rss)
declare -A answers=()
for _ in $(seq "$reloads"); do
  code=$(curl -s -o /dev/null -w '%{http_code}' -X POST -H "Authorization: Bearer $token" \
    "http://127.0.0.1:$port/api/plugins/$plugin/reload")
  answers[$code]=$(( ${answers[$code]:-0} + 1 ))
done
after=$(rss)
echo "plugin $plugin, $reloads reload requests:"
for code in "${!answers[@]}"; do echo "  HTTP $code: ${answers[$code]}"; done
echo "VmRSS before: $before kB, after: $after kB, growth: $(( after - before )) kB"
