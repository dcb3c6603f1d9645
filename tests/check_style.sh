#!/usr/bin/env bash
# Style gate for changed C++: clang-format-14 on the changed lines, clang-tidy-14 (.clang-tidy) on the changed files,
# then tests/check_kernel_shape.py on the whole tree. Exits non-zero on any finding and prints the command that
# fixes it.
#
# Usage: tests/check_style.sh [BASE [BUILD_DIR]]
#   BASE       commit to compare with (working tree, committed or not, plus untracked files). Default: the merge-base
#              with origin/main when that ref exists, else HEAD~1, else every tracked C++ file is checked whole.
#   BUILD_DIR  a configured build holding compile_commands.json (default: build).
# Environment: CHECK_STYLE_JOBS (parallel clang-tidy runs, default: nproc).
# Debian packages: clang-format-14 (also ships git-clang-format-14), clang-tidy-14, universal-ctags, python3, git.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 2
root=$(pwd -P)

dirs=(kernel libs services sdk plugins rcanctl tests bench)
exts=cpp,cc,cxx,hpp,hh,hxx,h,inl,ipp
cxx_re="\\.(${exts//,/|})\$"
dirs_re="^($(IFS='|'; echo "${dirs[*]}"))/"
build=${2:-build}
[[ $build = /* ]] || build="$root/$build"
jobs=${CHECK_STYLE_JOBS:-$(nproc)}
failed=()
started=$SECONDS

for tool in clang-format-14 git-clang-format-14 clang-tidy-14 python3; do
  command -v "$tool" > /dev/null || { echo "check_style: $tool not found (apt-get install clang-format-14 clang-tidy-14)" >&2; exit 2; }
done

# ---- which files -----------------------------------------------------------------------------------------------
if [ $# -ge 1 ] && [ -n "$1" ]; then
  base=$(git rev-parse --verify -q "$1^{commit}") || { echo "check_style: '$1' is not a commit" >&2; exit 2; }
elif git rev-parse --verify -q origin/main > /dev/null; then
  base=$(git merge-base HEAD origin/main)
elif git rev-parse --verify -q HEAD~1 > /dev/null; then
  base=$(git rev-parse HEAD~1)
else
  base=""
fi

if [ -n "$base" ]; then
  # Changed since BASE (deleted ones skipped), plus files git does not track yet.
  mapfile -t files < <({ git diff --name-only --diff-filter=d "$base" --; git ls-files --others --exclude-standard; } |
                       grep -E "$dirs_re" | grep -E "$cxx_re" | sort -u)
  mapfile -t untracked < <(git ls-files --others --exclude-standard | grep -E "$dirs_re" | grep -E "$cxx_re")
  echo "check_style: ${#files[@]} changed C++ files since $(git rev-parse --short "$base")"
else
  mapfile -t files < <(git ls-files | grep -E "$dirs_re" | grep -E "$cxx_re")
  untracked=()
  echo "check_style: no base commit; checking all ${#files[@]} tracked C++ files whole"
fi
existing=()
for f in "${files[@]}"; do [ -f "$f" ] && existing+=("$f"); done
files=("${existing[@]+"${existing[@]}"}")

# ---- clang-format: changed lines only ----------------------------------------------------------------------------
if [ ${#files[@]} -gt 0 ]; then
  echo "== clang-format-14"
  format_bad=0
  tracked=()
  for f in "${files[@]}"; do
    [[ " ${untracked[*]+"${untracked[*]}"} " == *" $f "* ]] || tracked+=("$f")
  done
  if [ -n "$base" ] && [ ${#tracked[@]} -gt 0 ]; then
    out=$(git-clang-format-14 --binary clang-format-14 --style file --extensions "$exts" --diff "$base" -- "${tracked[@]}" 2>&1)
    if [ -n "$out" ] && ! grep -qE '^(no modified files to format|clang-format did not modify any files)$' <<< "$out"; then
      echo "$out"
      format_bad=1
    fi
  fi
  # New files (untracked), or every file when there is no base: the whole file is new.
  whole=("${untracked[@]+"${untracked[@]}"}")
  [ -n "$base" ] || whole=("${files[@]}")
  for f in "${whole[@]+"${whole[@]}"}"; do
    if ! out=$(clang-format-14 --style=file --dry-run --Werror "$f" 2>&1); then
      grep -c 'error:' <<< "$out" | xargs printf '%s: %s places to reformat, first ones:\n' "$f"
      head -12 <<< "$out"
      format_bad=1
    fi
  done
  if [ $format_bad -ne 0 ]; then
    failed+=("clang-format")
    if [ -n "$base" ]; then
      echo "fix: git clang-format-14 --binary clang-format-14 --style file $(git rev-parse --short "$base")" \
           "-- <files>   (new files: clang-format-14 -i <file>)"
    else
      echo "fix: clang-format-14 -i <file>"
    fi
  else
    echo "clang-format: ok"
  fi
fi

# ---- clang-tidy: changed files -----------------------------------------------------------------------------------
if [ ${#files[@]} -gt 0 ]; then
  echo "== clang-tidy-14 ($build)"
  if [ ! -f "$build/compile_commands.json" ]; then
    echo "no $build/compile_commands.json"
    echo "fix: cmake -S . -B $build -G Ninja   (CMAKE_EXPORT_COMPILE_COMMANDS is on), then run this again"
    failed+=("clang-tidy")
  else
    # A changed header is checked through a unit that compiles it: its own .cpp (same folder, else same name
    # anywhere), else the first compiled file that includes it.
    mapfile -t units < <(python3 - "$build/compile_commands.json" "$root" "${files[@]}" <<'PY'
import json, os, re, sys
db, root, files = sys.argv[1], sys.argv[2], sys.argv[3:]
known = []
for entry in json.load(open(db)):
    path = os.path.normpath(os.path.join(entry.get("directory", ""), entry["file"]))
    rel = os.path.relpath(path, root)
    if path.startswith(root + os.sep) and rel not in known:
        known.append(rel)
known.sort()
sources = (".cpp", ".cc", ".cxx")

def includer_of(header):
    name = re.escape(os.path.basename(header))
    pattern = re.compile(r'^\s*#\s*include\s*["<]([^">]*/)?' + name + r'[">]', re.M)
    for unit in known:
        try:
            with open(os.path.join(root, unit), encoding="utf-8", errors="replace") as f:
                if pattern.search(f.read()):
                    return unit
        except OSError:
            pass
    return None

out = []
for f in files:
    stem, ext = os.path.splitext(f)
    if ext in sources:
        unit = f if f in known else None
    else:
        unit = next((stem + s for s in sources if stem + s in known), None)
        base = os.path.basename(stem)
        unit = unit or next((u for u in known if os.path.splitext(os.path.basename(u))[0] == base), None)
        unit = unit or includer_of(f)
    if unit is None:
        print(f"skip\t{f}")
    elif unit not in out:
        out.append(unit)
        print(f"unit\t{unit}")
PY
    )
    to_check=()
    for line in "${units[@]+"${units[@]}"}"; do
      kind=${line%%$'\t'*}; f=${line#*$'\t'}
      if [ "$kind" = skip ]; then echo "  (not compiled in $build, not checked: $f)"; else to_check+=("$f"); fi
    done
    if [ ${#to_check[@]} -gt 0 ]; then
      logs=$(mktemp -d)
      trap 'rm -rf "$logs"' EXIT
      header_filter="^$root/($(IFS='|'; echo "${dirs[*]}"))/.*\\.(h|hpp)\$"
      export build header_filter logs
      # Every unit also runs readability-function-size; its findings are kept for kernel/ only (below).
      # shellcheck disable=SC2016  # expanded by the inner bash
      printf '%s\0' "${to_check[@]}" | xargs -0 -P "$jobs" -n 1 bash -c '
        log="$logs/$(echo "$1" | tr / _).log"
        clang-tidy-14 -p "$build" --quiet --header-filter="$header_filter" --checks=readability-function-size "$1" \
          > "$log" 2>&1 || true' _
      # Only findings on the changed lines of the changed files count (a too-long function: when it overlaps them),
      # as for clang-format; compile errors always count.
      if python3 - "$root" "$base" "$logs" "${files[@]}" <<'PY'
import glob, os, re, subprocess, sys
root, base, logs, files = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
untracked = set(subprocess.run(["git", "ls-files", "--others", "--exclude-standard"], cwd=root,
                               capture_output=True, text=True).stdout.split())
changed = {}  # path -> list of (first, last) changed lines; None: the whole file
for f in files:
    if not base or f in untracked:
        changed[f] = None
        continue
    diff = subprocess.run(["git", "diff", "-U0", base, "--", f], cwd=root, capture_output=True, text=True).stdout
    ranges = []
    for m in re.finditer(r"^@@ -\d+(?:,\d+)? \+(\d+)(?:,(\d+))? @@", diff, re.M):
        first, count = int(m.group(1)), int(m.group(2) or 1)
        ranges.append((first, first + max(count, 1) - 1))  # a pure deletion marks the line after it
    changed[f] = ranges

head = re.compile(r"^(/[^:]+):(\d+):\d+: (error|warning): (.*?)(?: \[([^\]]+)\])?$")
kept = []
for log in sorted(glob.glob(os.path.join(logs, "*.log"))):
    block = None
    for line in open(log, encoding="utf-8", errors="replace").read().splitlines():
        m = head.match(line)
        if m:
            block = [m, [line]]
            kept.append(block)
        elif block is not None and not re.match(r"^\d+ (warning|error)s? generated\.$|^Suppressed \d+ warnings|"
                                                r"^Use -header-filter|^Error while processing", line):
            block[1].append(line)

seen, findings = set(), []
for m, lines in kept:
    path, line, checks = m.group(1), int(m.group(2)), m.group(5) or ""
    rel = os.path.relpath(path, root)
    span = (line, line)
    if "readability-function-size" in checks:
        if not rel.startswith("kernel/"):
            continue
        n = re.search(r"note: (\d+) lines including", "\n".join(lines))
        span = (line, line + int(n.group(1)) - 1) if n else span
    if not checks or "clang-diagnostic-error" in checks:
        pass  # the file does not compile: always a finding
    elif rel not in changed:
        continue
    elif changed[rel] is not None and not any(a <= span[1] and span[0] <= b for a, b in changed[rel]):
        continue
    key = (rel, line, checks)
    if key not in seen:  # a header's finding is reported once, whichever unit saw it
        seen.add(key)
        findings.append("\n".join(lines))
print("\n".join(findings))
sys.exit(1 if findings else 0)
PY
      then
        echo "clang-tidy: ok (${#to_check[@]} files)"
      else
        failed+=("clang-tidy")
        echo "fix: the findings above by hand, or clang-tidy-14 -p $build --fix <file> where a fix is offered"
      fi
    fi
  fi
fi

# ---- kernel shape --------------------------------------------------------------------------------------------------
echo "== tests/check_kernel_shape.py"
if ! python3 tests/check_kernel_shape.py "$root"; then
  failed+=("kernel shape")
  echo "fix: the report above (limits and allowlist at the top of tests/check_kernel_shape.py)"
fi

echo
if [ ${#failed[@]} -gt 0 ]; then
  echo "check_style: FAILED: ${failed[*]} ($((SECONDS - started)) s)"
  exit 1
fi
echo "check_style: all passed ($((SECONDS - started)) s)"
