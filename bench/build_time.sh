#!/usr/bin/env bash
# Clean builds of commits, one after the other, in CI's configuration (g++ 12, unity, RelWithDebInfo, tests, no
# benchmarks), each in a worktree of its own; then the include graph itself: lines after preprocessing, summed over
# every translation unit of a non-unity configuration (what a narrower include graph shrinks, whatever the unity
# batches do). Run it on an otherwise idle machine.
#   bench/build_time.sh REV...        e.g. bench/build_time.sh bd04ec6 HEAD
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
work=$(mktemp -d /tmp/rcand-build-time.XXXXXX)
trap 'for d in "$work"/src-*; do git -C "$repo" worktree remove --force "$d" 2>/dev/null || true; done; rm -rf "$work"' EXIT
for rev in "$@"; do
  dir=$work/src-$rev
  git -C "$repo" worktree add -f --detach "$dir" "$rev" > /dev/null
  cmake -S "$dir" -B "$dir/b" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_UNITY_BUILD=ON -DRCAND_BUILD_TESTS=ON \
        -DRCAND_BUILD_BENCH=OFF > /dev/null
  start=$(date +%s)
  cmake --build "$dir/b" > "$work/build-$rev.log"
  end=$(date +%s)
  cmake -S "$dir" -B "$dir/lint" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRCAND_BUILD_TESTS=ON -DRCAND_BUILD_BENCH=OFF \
        > /dev/null
  graph=$(python3 - "$dir/lint/compile_commands.json" <<'PY'
import json, shlex, subprocess, sys
units = lines = 0
for c in json.load(open(sys.argv[1])):
    argv = shlex.split(c["command"])
    out = []
    skip = False
    for a in argv:
        if skip:
            skip = False
        elif a in ("-o", "-MT", "-MF"):
            skip = True
        elif a not in ("-c", "-MD"):
            out.append(a)
    r = subprocess.run(out + ["-E", "-P"], cwd=c["directory"], capture_output=True, text=True)
    units += 1
    lines += r.stdout.count("\n")
print(f"{units} translation units, {lines} preprocessed lines ({lines // max(units, 1)} per unit)")
PY
)
  printf '%s: build %d s (%s ninja steps); %s\n' "$(git -C "$repo" rev-parse --short "$rev")" "$((end - start))" \
         "$(grep -c '^\[' "$work/build-$rev.log")" "$graph"
done
