#!/usr/bin/env python3
"""Checks that kernel/ stays a microkernel and that the layers keep their direction.

Usage: tests/check_kernel_shape.py [REPO_ROOT]   (default: the current directory)

  a) size:        non-blank, non-comment lines of C++ under kernel/ <= KERNEL_LINE_LIMIT
  b) functions:   no function under kernel/ longer than FUNCTION_LINE_LIMIT lines (universal-ctags finds them)
  c) layering:    kernel/ includes nothing from services/, plugins/, rcanctl/; libs/ nothing from kernel/,
                  services/, plugins/; kernel CMake names no plugin path or plugin target
  d) capabilities: only the standard capability table names "nav", "teleop", ... as string literals

Prints a report and exits 1 on any failure (2 when it cannot run, e.g. without universal-ctags).
Needs python3 (stdlib only) and Debian's universal-ctags.
"""

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time

# ---- The limits and the agreed exceptions -------------------------------------------------------------------------

KERNEL_LINE_LIMIT = 6000
FUNCTION_LINE_LIMIT = 60

# Functions allowed past FUNCTION_LINE_LIMIT: "path:Name" (Name as the report prints it, e.g. "Api::dispatch";
# overloads share an entry). Only for data tables (one row per line, no logic); each entry says why.
LONG_FUNCTION_ALLOWLIST: dict = {}

STANDARD_CAPABILITIES = ("nav", "teleop", "vision", "chat", "arm")
# The kernel files that may spell the standard capability names: the table and its header (which names each one
# once, as a constant). While they do not exist, any file whose name contains CAPABILITY_TABLE_HINT takes their place.
CAPABILITY_TABLE_FILES = ("kernel/registry/standard_capabilities.cpp", "kernel/registry/standard_capabilities.hpp")
CAPABILITY_TABLE_HINT = "standard_capabilit"

KERNEL_DIR = "kernel"
# Layer -> the top-level folders its C++ must not include.
FORBIDDEN_INCLUDES = {
    "kernel": ("services", "plugins", "rcanctl"),
    "libs": ("kernel", "services", "plugins"),
}
PLUGINS_DIR = "plugins"
# Top-level folders an include such as "libs/http/server.hpp" or <rcand/kernel/core/api.hpp> can name.
AREAS = ("kernel", "libs", "services", "plugins", "rcanctl", "sdk", "tests", "bench")

COUNTED_SUFFIXES = (".cpp", ".hpp", ".h")  # what the size limit counts
CXX_SUFFIXES = (".cpp", ".cc", ".cxx", ".hpp", ".hh", ".hxx", ".h", ".inl", ".ipp")
HEADER_SUFFIXES = (".hpp", ".hh", ".hxx", ".h", ".inl", ".ipp")


# ---- A small C++ scanner: which lines hold code, the string literals, the #includes ----------------------------

STRING_PREFIXES = {"L", "u", "U", "u8", "R", "LR", "uR", "UR", "u8R"}
INCLUDE_RE = re.compile(r'#[ \t]*include[ \t]*([<"])([^>"\n]*)[>"]')


class Scan:
    def __init__(self):
        self.code_lines = set()  # 1-based numbers of lines with anything but whitespace and comments
        self.literals = []  # (line, body) of every "..." literal, escapes left as written
        self.includes = []  # (line, quoted, path)


def scan_cxx(text):
    """Good enough for counting and grepping our own code: comments, strings, raw strings, char literals and digit
    separators (1'000) are told apart; macros and #if 0 are not interpreted."""
    out = Scan()
    n = len(text)
    i = 0
    line = 1
    line_start = True  # nothing but whitespace so far on this line (a # here starts a directive)
    while i < n:
        c = text[i]
        if c == "\n":
            line += 1
            line_start = True
            i += 1
            continue
        if c in " \t\r\f\v":
            i += 1
            continue
        if c == "\\" and text.startswith("\n", i + 1):
            line += 1
            i += 2
            continue
        if text.startswith("//", i):
            j = i + 2
            while j < n and text[j] != "\n":
                if text[j] == "\\" and text.startswith("\n", j + 1):  # a continued // comment
                    line += 1
                    j += 1
                j += 1
            i = j
            continue
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            line += text.count("\n", i, j)
            i = j
            continue

        out.code_lines.add(line)
        if c == "#" and line_start:
            line_start = False
            m = INCLUDE_RE.match(text, i)
            if m:
                out.includes.append((line, m.group(1) == '"', m.group(2).strip()))
                i = m.end()
            else:
                i += 1
            continue
        line_start = False

        if c.isalpha() or c == "_":
            j = i + 1
            while j < n and (text[j].isalnum() or text[j] == "_"):
                j += 1
            word = text[i:j]
            if j < n and text[j] in "\"'" and word in STRING_PREFIXES:
                i, line = _literal(text, j, word, line, out)
            else:
                i = j
            continue
        if c.isdigit() or (c == "." and i + 1 < n and text[i + 1].isdigit()):
            j = i + 1
            while j < n:
                ch = text[j]
                if ch.isalnum() or ch in "_.":
                    j += 1
                elif ch == "'" and j + 1 < n and text[j + 1].isalnum():  # digit separator
                    j += 2
                elif ch in "+-" and text[j - 1] in "eEpP":
                    j += 1
                else:
                    break
            i = j
            continue
        if c in "\"'":
            i, line = _literal(text, i, "", line, out)
            continue
        i += 1
    return out


def _literal(text, i, prefix, line, out):
    """Reads the literal whose quote is at text[i]; returns (index after it, line after it)."""
    n = len(text)
    quote = text[i]
    start_line = line
    if quote == '"' and prefix.endswith("R"):
        paren = text.find("(", i + 1)
        if paren < 0:
            return i + 1, line
        delim = text[i + 1:paren]
        end = text.find(")" + delim + '"', paren + 1)
        if end < 0:
            end = n
        body = text[paren + 1:end]
        after = min(n, end + len(delim) + 2)
        for k, part in enumerate(text[i:after].split("\n")):  # a raw string's lines count unless blank
            if part.strip():
                out.code_lines.add(start_line + k)
        line += text.count("\n", i, after)
    else:
        j = i + 1
        while j < n and text[j] != quote and text[j] != "\n":
            if text[j] == "\\" and j + 1 < n:
                if text[j + 1] == "\n":
                    line += 1
                j += 2
                continue
            j += 1
        body = text[i + 1:j]
        after = j + 1 if j < n and text[j] == quote else j
    if quote == '"':
        out.literals.append((start_line, body))
    return after, line


# ---- The tree ------------------------------------------------------------------------------------------------------

def skipped_dir(name):
    return name.startswith(".") or name.startswith("build") or name == "__pycache__"


def files_under(root, top, suffixes):
    """Repo-relative paths of the files under root/top ending in suffixes, sorted."""
    found = []
    base = os.path.join(root, top)
    for dirpath, dirnames, filenames in os.walk(base):
        dirnames[:] = sorted(d for d in dirnames if not skipped_dir(d))
        for name in filenames:
            if name.endswith(suffixes):
                found.append(os.path.relpath(os.path.join(dirpath, name), root).replace(os.sep, "/"))
    return sorted(found)


def cmake_files_under(root, top):
    found = []
    for dirpath, dirnames, filenames in os.walk(os.path.join(root, top)):
        dirnames[:] = sorted(d for d in dirnames if not skipped_dir(d))
        for name in filenames:
            if name == "CMakeLists.txt" or name.endswith(".cmake"):
                found.append(os.path.relpath(os.path.join(dirpath, name), root).replace(os.sep, "/"))
    return sorted(found)


def read(root, rel):
    with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
        return f.read()


class Report:
    def __init__(self):
        self.failed = []

    def section(self, name, detail, ok, lines):
        print(f"[{'PASS' if ok else 'FAIL'}] {name}: {detail}")
        for text in lines:
            print(f"    {text}")
        print()
        if not ok:
            self.failed.append(name)


# ---- a) size -------------------------------------------------------------------------------------------------------

def check_size(root, scans, report):
    counts = sorted(((len(s.code_lines), p) for p, s in scans.items() if p.endswith(COUNTED_SUFFIXES)),
                    key=lambda c: (-c[0], c[1]))
    total = sum(c for c, _ in counts)
    lines = [f"{total} code lines in {len(counts)} files under {KERNEL_DIR}/ (limit {KERNEL_LINE_LIMIT}"
             + (f", {total - KERNEL_LINE_LIMIT} over" if total > KERNEL_LINE_LIMIT else "") + ")",
             "largest:"]
    lines += [f"  {c:6d}  {p}" for c, p in counts[:10]]
    report.section("a) kernel size", f"{total} code lines, limit {KERNEL_LINE_LIMIT}", total <= KERNEL_LINE_LIMIT, lines)


# ---- b) function length --------------------------------------------------------------------------------------------

def find_ctags():
    for name in ("ctags-universal", "universal-ctags", "ctags"):
        path = shutil.which(name)
        if not path:
            continue
        try:
            version = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=10).stdout
        except (OSError, subprocess.SubprocessError):
            continue
        if "Universal Ctags" in version:
            return path
    return None


def display_name(tag):
    # Show the class for members (Api::dispatch); namespaces, anonymous ones included, only add noise.
    name = tag["name"]
    if name.startswith("__anon"):  # ctags tags lambdas as anonymous functions inside their function
        owners = [part for part in tag.get("scope", "").split("::") if part and not part.startswith("__anon")]
        return f"lambda in {owners[-1]}" if owners else "lambda"
    if tag.get("scopeKind") in ("class", "struct", "union") and tag.get("scope"):
        owner = tag["scope"].split("::")[-1]
        if not owner.startswith("__anon"):
            name = f"{owner}::{name}"
    return name


def function_spans(root, paths):
    """(path, line, display name, length in lines) of every function definition ctags finds in paths."""
    ctags = find_ctags()
    if ctags is None:
        print("error: universal-ctags not found (Debian: apt-get install universal-ctags)", file=sys.stderr)
        sys.exit(2)
    cmd = [ctags, "--options=NONE", "--language-force=C++", "--kinds-C++=f", "--fields=+ne",
           "--output-format=json", "--sort=no", "-f", "-", "-L", "-"]
    run = subprocess.run(cmd, cwd=root, input="\n".join(paths) + "\n", capture_output=True, text=True, timeout=120)
    if run.returncode != 0:
        print(f"error: ctags failed ({run.returncode}): {run.stderr.strip()}", file=sys.stderr)
        sys.exit(2)
    spans = []
    for raw in run.stdout.splitlines():
        try:
            tag = json.loads(raw)
        except ValueError:
            continue
        if tag.get("_type") != "tag" or tag.get("kind") not in ("function", "method") or "end" not in tag:
            continue
        spans.append((tag["path"], tag["line"], display_name(tag), tag["end"] - tag["line"] + 1))
    return spans


def check_functions(root, paths, report):
    spans = function_spans(root, paths)
    long_ones = [s for s in spans if s[3] > FUNCTION_LINE_LIMIT]
    offenders = [s for s in long_ones if f"{s[0]}:{s[2]}" not in LONG_FUNCTION_ALLOWLIST]
    allowed = len(long_ones) - len(offenders)
    offenders.sort(key=lambda s: (-s[3], s[0], s[1]))
    lines = [f"{len(spans)} functions checked; {len(offenders)} longer than {FUNCTION_LINE_LIMIT} lines"
             + (f" ({allowed} more allowlisted)" if allowed else "")]
    lines += [f"  {length:4d} lines  {path}:{line}  {name}" for path, line, name, length in offenders]
    stale = sorted(set(LONG_FUNCTION_ALLOWLIST) - {f"{s[0]}:{s[2]}" for s in long_ones})
    lines += [f"  note: allowlist entry no longer needed: {key}" for key in stale]
    report.section("b) function length", f"{len(offenders)} kernel functions over {FUNCTION_LINE_LIMIT} lines",
                   not offenders, lines)


# ---- c) layering ---------------------------------------------------------------------------------------------------

def top_of(rel):
    return rel.split("/", 1)[0]


def header_index(root):
    """Header file name -> repo paths, to resolve includes found through -I (e.g. "waypoint_plan.hpp")."""
    index = {}
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if not skipped_dir(d)]
        for name in filenames:
            if name.endswith(HEADER_SUFFIXES):
                rel = os.path.relpath(os.path.join(dirpath, name), root).replace(os.sep, "/")
                index.setdefault(name, []).append(rel)
    return index


def include_targets(root, includer, quoted, path, index):
    """The top-level folders the include can mean: ["libs"], several when ambiguous, [] for system headers."""
    norm = os.path.normpath(path).replace(os.sep, "/")
    if quoted:  # the compiler looks next to the includer first
        local = os.path.normpath(os.path.join(os.path.dirname(includer), path)).replace(os.sep, "/")
        if not local.startswith("../") and os.path.isfile(os.path.join(root, local)):
            return [top_of(local)]
    if not norm.startswith("../") and "/" in norm and os.path.isfile(os.path.join(root, norm)):
        return [top_of(norm)]  # repo-relative: "kernel/safety/estop.hpp"
    matches = [p for p in index.get(os.path.basename(norm), []) if p.endswith("/" + norm)]
    if matches:  # found through some include directory: <rcand/kernel/core/api.hpp>, "waypoint_plan.hpp"
        return sorted({top_of(p) for p in matches})
    parts = norm.split("/")
    if parts[0] == "rcand":
        parts = parts[1:]
    if len(parts) > 1 and parts[0] in AREAS:  # not written yet, but named by its layer
        if quoted and os.path.isdir(os.path.join(root, os.path.dirname(includer), parts[0])):
            return [top_of(includer)]  # kernel/plugins/... seen from kernel/
        return [parts[0]]
    return []


def strip_cmake_comments(text):
    text = re.sub(r"#\[(=*)\[.*?\]\1\]", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    out = []
    for line in text.split("\n"):
        quoted = False
        cut = len(line)
        for k, ch in enumerate(line):
            if ch == '"' and (k == 0 or line[k - 1] != "\\"):
                quoted = not quoted
            elif ch == "#" and not quoted:
                cut = k
                break
        out.append(line[:cut])
    return out


TARGET_DEF_RE = re.compile(r"\b(?:add_library|rcand_add_plugin)\s*\(\s*\"?([A-Za-z0-9_.+:-]+)", re.I)


def plugin_targets(root):
    """Targets the plugin folders define: add_library() and rcand_add_plugin() (a MODULE add_library)."""
    targets = {}
    for rel in cmake_files_under(root, PLUGINS_DIR):
        for number, line in enumerate(strip_cmake_comments(read(root, rel)), 1):
            for m in TARGET_DEF_RE.finditer(line):
                targets.setdefault(m.group(1), f"{rel}:{number}")
    return targets


def cmake_plugin_paths(root, rel, line):
    """Words on a kernel CMake line that resolve into the top-level plugins/ folder."""
    here = os.path.dirname(rel)
    hits = []
    for word in re.findall(r'"[^"]*"|[^\s()"]+', line):
        word = word.strip('"')
        if PLUGINS_DIR not in word:
            continue
        base, rest = here, word
        m = re.match(r"\$\{(\w+)\}/?", word)
        if m and m.group(1) in ("CMAKE_CURRENT_SOURCE_DIR", "CMAKE_CURRENT_LIST_DIR"):
            rest = word[m.end():]
        elif m and m.group(1).endswith("SOURCE_DIR"):  # CMAKE_SOURCE_DIR, PROJECT_SOURCE_DIR, rcand_SOURCE_DIR
            base, rest = "", word[m.end():]
        if "${" in rest or "$<" in rest or rest.startswith("/"):
            continue  # a variable we cannot know, a generator expression, an absolute path: the target check stays
        path = os.path.join(base, rest)
        resolved = os.path.normpath(path).replace(os.sep, "/")
        if top_of(resolved) == PLUGINS_DIR:
            hits.append(word)
    return hits


def check_layering(root, report):
    index = header_index(root)
    problems = []
    for layer, forbidden in FORBIDDEN_INCLUDES.items():
        for rel in files_under(root, layer, CXX_SUFFIXES):
            for line, quoted, path in scan_cxx(read(root, rel)).includes:
                targets = include_targets(root, rel, quoted, path, index)
                if targets and all(t in forbidden for t in targets):
                    spelled = f'"{path}"' if quoted else f"<{path}>"
                    problems.append(f"{rel}:{line}: includes {spelled} from {'/'.join(targets)}/ "
                                    f"({layer}/ must not include {', '.join(f + '/' for f in forbidden)})")

    targets = plugin_targets(root)
    names = {name: re.compile(r"(?<![\w.+-])(?<!::)" + re.escape(name) + r"(?![\w.+-])(?!::)") for name in targets}
    for rel in cmake_files_under(root, KERNEL_DIR):
        for number, line in enumerate(strip_cmake_comments(read(root, rel)), 1):
            for word in cmake_plugin_paths(root, rel, line):
                problems.append(f"{rel}:{number}: names the plugin path {word}")
            for name, pattern in names.items():
                if pattern.search(line):
                    problems.append(f"{rel}:{number}: names the plugin target {name} (defined at {targets[name]})")

    lines = [f"kernel/ -> not {', '.join(FORBIDDEN_INCLUDES['kernel'])}; libs/ -> not "
             f"{', '.join(FORBIDDEN_INCLUDES['libs'])}; kernel CMake -> no plugin path or target "
             f"({len(targets)} plugin targets known)"]
    report.section("c) layering", f"{len(problems)} violations", not problems, lines + problems)


# ---- d) capability names -------------------------------------------------------------------------------------------

def capability_table_files(root, kernel_files):
    present = {p for p in CAPABILITY_TABLE_FILES if os.path.isfile(os.path.join(root, p))}
    if present:
        return present
    return {p for p in kernel_files if CAPABILITY_TABLE_HINT in os.path.basename(p)}


def check_capabilities(root, scans, report):
    names = set(STANDARD_CAPABILITIES)
    tables = capability_table_files(root, scans)
    hits = {}  # path -> [(line, name)]
    for path, scan in scans.items():
        for line, body in scan.literals:
            if body in names:
                hits.setdefault(path, []).append((line, body))
    problems = []
    for path in sorted(hits):
        if path in tables:
            continue
        problems += [f'{path}:{line}: "{name}"' for line, name in hits[path]]
    holders = sorted(p for p in hits if p in tables)
    if len(holders) > 1:  # the fallback may match several files; the names still belong in one
        problems.append(f"the standard names are spelled in {len(holders)} table files, expected one: "
                        + ", ".join(holders))
    where = ", ".join(sorted(tables)) if tables else f"none yet ({CAPABILITY_TABLE_FILES[0]} or *{CAPABILITY_TABLE_HINT}*)"
    lines = [f"names {', '.join(STANDARD_CAPABILITIES)} only in the table: {where}"]
    if problems:
        lines.append(f"{sum(len(v) for p, v in hits.items() if p not in tables)} literals in "
                     f"{len([p for p in hits if p not in tables])} other files:")
    report.section("d) capability names", f"{len(problems)} outside the table", not problems, lines + problems)


# ---- main ------------------------------------------------------------------------------------------------------------

def main(argv):
    if len(argv) > 2 or (len(argv) == 2 and argv[1] in ("-h", "--help")):
        print(__doc__.strip())
        return 0 if len(argv) == 2 else 2
    root = os.path.abspath(argv[1] if len(argv) == 2 else ".")
    if not os.path.isdir(os.path.join(root, KERNEL_DIR)):
        print(f"error: {root} has no {KERNEL_DIR}/ (run from the repo root or pass it)", file=sys.stderr)
        return 2
    started = time.monotonic()
    kernel_files = files_under(root, KERNEL_DIR, CXX_SUFFIXES)
    scans = {p: scan_cxx(read(root, p)) for p in kernel_files}
    report = Report()
    print(f"kernel shape of {root}\n")
    check_size(root, scans, report)
    check_functions(root, kernel_files, report)
    check_layering(root, report)
    check_capabilities(root, scans, report)
    took = time.monotonic() - started
    if report.failed:
        print(f"kernel shape: FAILED ({', '.join(report.failed)}) in {took:.1f} s")
        return 1
    print(f"kernel shape: all checks passed in {took:.1f} s")
    return 0


if __name__ == "__main__":
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # quiet when piped into head
    sys.exit(main(sys.argv))
