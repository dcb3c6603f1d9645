#!/usr/bin/env bash
# Every shell example of README.md's "Talking to the simulated robot", run as written (issue 29 item 6): a fresh
# clone's layout (config/sim-rover.rcan.yaml with config/dev-jwt.secret at mode 0644, as git leaves it; build/ = this
# build tree), rcand started by the README's own command, then each example line in turn in one shell. rcand must
# start without a warning (a fresh clone's first minute). Each example must exit 0 with nothing on stderr containing
# "warning", and curl's answers must be 2xx (a curl shell function adds --fail: an example that the robot refuses
# counts as failed). Lines that run until Ctrl-C (--follow, watch) get a Ctrl-C after 2 s; --hold reads an empty
# stdin, which releases it. `rcanctl doctor` also checks this machine (avahi-daemon, clock sync): it may exit 1 for
# those two alone, never for the config, the robot, the e-stop or the plugins.
# The whole run is in a network namespace of its own, so 127.0.0.1:8000 is this test's: nothing is rewritten.
# Usage: readme_examples_test.sh SOURCE_DIR BUILD_DIR
set -u
src=$(realpath "$1")
bin=$(realpath "$2")

if [[ -z "${RCAND_README_NETNS:-}" ]]; then
  # Root (CI) gets a plain network namespace; anyone else a user namespace mapped to root.
  for flags in "-n" "-rn"; do
    if unshare $flags true 2>/dev/null; then
      exec unshare $flags env RCAND_README_NETNS=1 bash "$0" "$@"
    fi
  done
  echo "readme_examples_test: cannot make a network namespace (unshare -n / -rn): 127.0.0.1:8000 is not ours" >&2
  exit 1
fi
ip link set lo up 2>/dev/null || /usr/sbin/ip link set lo up || exit 1

work=$(mktemp -d /tmp/rcand-readme.XXXXXX)
rcand_pid=
cleanup() {
  [[ -n "$rcand_pid" ]] && kill "$rcand_pid" 2>/dev/null && wait "$rcand_pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT

# The examples, extracted from the section: every line of its ```sh blocks.
examples=$(awk '/^### Talking to the simulated robot/ {on = 1; next}
                on && /^##/ {exit}
                on && /^```sh/ {block = 1; next}
                block && /^```/ {block = 0; next}
                block {print}' "$src/README.md")
count=$(grep -cvE '^[[:space:]]*(#|$)' <<<"$examples")
if ((count < 20)); then
  echo "readme_examples_test: found only $count example lines in README.md's 'Talking to the simulated robot'" >&2
  exit 1
fi

mkdir -p "$work/config" "$work/build"
cp "$src/config/sim-rover.rcan.yaml" "$src/config/dev-jwt.secret" "$work/config/"
chmod 0644 "$work/config/dev-jwt.secret"  # what git leaves in a fresh clone
for dir in kernel rcanctl plugins; do ln -s "$bin/$dir" "$work/build/$dir"; done  # build/state stays this test's own
cd "$work" || exit 1

build/kernel/rcand --config config/sim-rover.rcan.yaml >"$work/rcand.out" 2>"$work/rcand.err" &
rcand_pid=$!
# rcand serves once it listens; its capabilities answer 503 STARTING until "capabilities started" (docs/protocol.md
# §7.18): the examples below use them, so wait for both lines.
for _ in $(seq 1 300); do
  grep -q "capabilities started" "$work/rcand.out" && break
  kill -0 "$rcand_pid" 2>/dev/null || break
  sleep 0.1
done
if ! grep -q "listening on http://127.0.0.1:8000" "$work/rcand.out" || ! grep -q "capabilities started" "$work/rcand.out"; then
  echo "readme_examples_test: rcand did not start as README.md says:" >&2
  cat "$work/rcand.err" >&2
  exit 1
fi
failed=0
if grep -qi "warn" "$work/rcand.err"; then
  echo "rcand started with warnings:" >&2
  grep -i "warn" "$work/rcand.err" >&2
  failed=1
fi

curl() { command curl --fail "$@"; }
# doctor's rows (CHECK RESULT DETAIL FIX): a PROBLEM other than the machine's mDNS daemon or clock is a failure.
doctor_only_machine_problems() {
  ! grep -E "^[a-zA-Z-]+ +PROBLEM" "$work/example.out" | grep -vqE "^(mDNS|clock) "
}
ran=0
while IFS= read -r line; do
  [[ "$line" =~ ^[[:space:]]*(#|$) ]] && continue
  command=$line
  [[ "$line" == *"--follow"* || "$line" == *"rcanctl watch"* ]] && command="timeout --preserve-status -s INT 2 $line"
  eval "$command" </dev/null >"$work/example.out" 2>"$work/example.err"
  status=$?
  [[ "$line" == *"rcanctl doctor"* ]] && ((status == 1)) && doctor_only_machine_problems && status=0
  ran=$((ran + 1))
  if ((status != 0)) || grep -qi "warning" "$work/example.err"; then
    echo "FAILED (exit $status): $line" >&2
    sed 's/^/  stdout: /' "$work/example.out" | head -20 >&2
    sed 's/^/  stderr: /' "$work/example.err" >&2
    failed=$((failed + 1))
  fi
done <<<"$examples"

echo "readme_examples_test: $ran examples, $failed failed"
((failed == 0))
