#!/usr/bin/env python3
"""Docs that name things that exist (issue 33 item 4): every file path, code symbol and protocol section that
README.md, docs/architecture.md and docs/protocol.md name in backticks must exist in the tree.

How it decides, for each `backticked` span outside fenced code blocks (<...> and a trailing :line or punctuation are
stripped first):
  * a path (a '/' in it, no spaces, not starting with '/' - those are HTTP or install paths): the file or folder
    exists at the root, under sdk/include/, or as the tail of a tracked path; {a,b} alternatives and * globs expand;
  * a bare file name with a source extension (.cpp .hpp .h .py .cmake .sh): some tracked file has that name;
  * a qualified symbol (`A::b`, `A::b(args)`): every part is a word of some C++ file, and the last two share a file;
  * a constant (`kName`), a call (`name()`/`name(args)`), a CamelCase type or a snake_case word: that word occurs in
    some tracked code, config, manifest or test file (the docs themselves do not count);
  * a name in parentheses right after a file, "`kernel/api/api.cpp` (`Api::serve`, `kStopPeerTimeout`)": the name
    (its last part) occurs in that very file;
  * "docs/protocol.md §N" (and "§N" right after it in "§9 and §14", "§3, §4") anywhere in the three docs: the section
    exists (a "## N." heading, or a "**N.M ..." rule).
Anything else (config keys with dots, JSON snippets, commands) is not checked. ALLOW lists the few names the docs use
on purpose that are not in the tree (the reference runtime's, the spec's, examples a vendor would write).
Prints each stale name with its line; exits 1 if there is any.
"""
import glob
import os
import re
import subprocess
import sys

ROOT = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), ".."))
DOCS = ["README.md", "docs/architecture.md", "docs/protocol.md"]
# Names the docs use on purpose that are not ours: a vendor's example, the reference runtime's, RCAN's.
ALLOW = {
    "conf.d/",  # the config's drop-in folder beside the robot's config file, at run time
    "config/presets/",  # the reference runtime's (OpenCastor's) folders, named where its presets are cited
    "config/rcan.schema.json",
    "picar_x",  # a reference runtime preset, by the short name README's preset table uses
}
SKIP_PREFIXES = ("build/", "build-")  # build outputs
CODE_EXT = (".cpp", ".hpp", ".h", ".py", ".cmake", ".sh", ".txt", ".json", ".yaml", ".yml", ".js", ".html", ".css", ".service",
            ".in", ".1")


def tracked():
    try:
        out = subprocess.run(["git", "-C", ROOT, "ls-files"], capture_output=True, text=True, check=True).stdout
        return [p for p in out.splitlines() if os.path.exists(os.path.join(ROOT, p))]
    except (OSError, subprocess.CalledProcessError):  # a source tarball: every file but build trees
        return [os.path.relpath(os.path.join(d, f), ROOT) for d, subdirs, files in os.walk(ROOT)
                for f in files if not os.path.relpath(d, ROOT).startswith(("build", ".git"))]


FILES = tracked()
DIRS = {os.path.dirname(p) for p in FILES}
for d in list(DIRS):
    while d:
        d = os.path.dirname(d)
        DIRS.add(d)
BASENAMES = {os.path.basename(p) for p in FILES}


def read(path):
    try:
        with open(os.path.join(ROOT, path), encoding="utf-8") as f:
            return f.read()
    except (UnicodeDecodeError, OSError):
        return ""


CPP = {p: read(p) for p in FILES if p.endswith((".cpp", ".hpp", ".h"))}
TEXT = "\n".join(read(p) for p in FILES if p.endswith(CODE_EXT) and p not in DOCS and not p.startswith("docs/"))
WORDS = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", TEXT + "\n".join(FILES)))  # file names count (preset names)
CPP_WORDS = {}
for path, text in CPP.items():
    for word in set(re.findall(r"[A-Za-z_~][A-Za-z0-9_]*", text)):
        CPP_WORDS.setdefault(word, set()).add(path)


def expand(path):
    m = re.search(r"\{([^{}]*)\}", path)
    if not m:
        return [path]
    return [x for alt in m.group(1).split(",") for x in expand(path[: m.start()] + alt + path[m.end():])]


def path_exists(path):
    for p in expand(path.rstrip("/")):
        for base in (ROOT, os.path.join(ROOT, "sdk/include")):
            if glob.glob(os.path.join(base, p)):
                break
        else:
            if not any(f.endswith("/" + p) for f in FILES) and not any(d.endswith("/" + p) for d in DIRS):
                return False
    return True


def sections():
    text = read("docs/protocol.md")
    found = set(re.findall(r"^## (\d+)\.", text, re.M))
    found |= set(re.findall(r"^\*\*(\d+(?:\.\d+)+)[ .*]", text, re.M))
    return found


SECTIONS = sections()
IDENT = r"[A-Za-z_][A-Za-z0-9_]*"


def check_span(span):
    """None if `span` names something that exists or is not a checked kind; else why it is stale."""
    s = span.strip().strip("<>").rstrip(".,;:")
    s = re.sub(r":\d+(-\d+)?$", "", s)
    if not s or s in ALLOW or " " in s or "://" in s or s.startswith(SKIP_PREFIXES):
        return None
    if "/" in s and not s.startswith(("/", "~", ".", "$")) and re.fullmatch(r"[\w.\-/{},*+]+", s):
        if not re.match(r"[\w.\-{]", s) or s.count("/") == 0:
            return None
        if re.fullmatch(r"[\w.\-]+/[\w.\-]+", s) and not re.search(r"\.\w+$", s) and s.split("/")[0] not in DIRS | BASENAMES:
            return None  # "a/b" prose (read/write, GET/HEAD), not a path
        return None if path_exists(s) else "no such file or folder"
    if re.fullmatch(r"[\w\-]+\.(cpp|hpp|h|py|cmake|sh)", s):
        return None if s in BASENAMES else "no such file"
    m = re.fullmatch(rf"({IDENT}(?:::{IDENT})+)(\(.*\))?(\(\))?", s.replace("::~", "::"))
    if m:
        parts = m.group(1).split("::")
        for part in parts:
            if part not in CPP_WORDS:
                return f"no C++ name '{part}'"
        if len(parts) >= 2 and not (CPP_WORDS[parts[-1]] & CPP_WORDS[parts[-2]]):
            return f"'{parts[-2]}' and '{parts[-1]}' share no C++ file"
        return None
    m = re.fullmatch(rf"({IDENT})\(.*\)", s)
    if m or re.fullmatch(r"k[A-Z]\w+|[A-Z][a-z0-9]+(?:[A-Z][a-z0-9]*)+|[a-z][a-z0-9]*(?:_[a-z0-9]+)+", s):
        word = m.group(1) if m else s
        return None if word in WORDS else f"'{word}' occurs in no code, config or test file"
    return None


def check_doc(doc):
    problems = []
    in_fence = False
    for number, line in enumerate(read(doc).splitlines(), 1):
        if line.lstrip().startswith("```"):
            in_fence = not in_fence
            continue
        if in_fence:
            continue
        for span in re.findall(r"`([^`]+)`", line):
            why = check_span(span)
            if why:
                problems.append(f"{doc}:{number}: `{span}`: {why}")
        for m in re.finditer(r"`([\w./\-]+\.\w+)` \(((?:`[^`]+`(?:, )?)+)\)", line):
            text = read(m.group(1)) if m.group(1) in FILES else ""
            for name in re.findall(r"`([^`]+)`", m.group(2)):
                word = re.sub(r"\(.*\)$", "", name).split("::")[-1]
                if text and re.fullmatch(IDENT, word) and name not in ALLOW and not re.search(rf"\b{word}\b", text):
                    problems.append(f"{doc}:{number}: `{name}` is not in {m.group(1)}")
        for m in re.finditer(r"docs/protocol\.md((?:,? (?:and |or )?§\d+(?:\.\d+)*)+)", line):
            for section in re.findall(r"§(\d+(?:\.\d+)*)", m.group(1)):
                if section not in SECTIONS:
                    problems.append(f"{doc}:{number}: docs/protocol.md §{section}: no such section")
    return problems


def main():
    problems = [p for doc in DOCS for p in check_doc(doc)]
    for p in problems:
        print(p)
    print(f"docs check: {len(problems)} stale name(s) in {', '.join(DOCS)}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
