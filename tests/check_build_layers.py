#!/usr/bin/env python3
"""The layering is the build's (issue 33 item 2, cmake/RcandModule.cmake): every compile of rcand's own modules and of
rcanctl sees exactly its layer's folders, so an #include across the rule fails to compile.

    tests/check_build_layers.py SOURCE_DIR BUILD_DIR

Reads BUILD_DIR/compile_commands.json. For each compile of a target under libs/, kernel/, services/ or rcanctl/, the
-I roots it gets must not include the source tree itself, and the repository folders reachable through them must be
exactly the layer's. Then, with a libs module's, a kernel module's and rcanctl's own flags, the compiler must accept a
probe that includes its layer's header and refuse one that includes the next layer's: the rule holds in the compiler,
not only in this script's reading of the flags.

Namespaces match folders too: a file of libs/<m>/ opens `rcand` or `rcand::<m>`, of kernel/ `rcand::kernel`, of
services/<m>/ `rcand::services` or `rcand::services::<m>`, of rcanctl/ `rcand::rcanctl`, of the SDK `rcand::sdk`
(each with anything nested), and none opens a namespace named after another module."""
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile

ALLOWED = {
    "libs": {"libs"},
    "kernel": {"libs", "kernel"},
    "services": {"libs", "kernel", "services"},
    "rcanctl": {"libs"},
}
FOLDERS = ("libs", "kernel", "services", "plugins", "rcanctl", "tests", "bench")
# One header per folder, included by a probe.
PROBE_HEADERS = {"libs": "libs/base/logging.hpp", "kernel": "kernel/kernel.hpp", "services": "services/telemetry/latency_histogram.hpp"}


def layer_of(command, build):
    output = command.get("output") or ""
    if not output:
        match = re.search(r"-o (\S+)", command["command"])
        output = match.group(1) if match else ""
    rel = os.path.relpath(os.path.join(command["directory"], output), build)
    top = rel.split(os.sep)[0]
    return top if top in ALLOWED else None


def include_roots(argv, directory):
    roots = []
    for i, arg in enumerate(argv):
        if arg in ("-I", "-isystem", "-iquote") and i + 1 < len(argv):
            roots.append(argv[i + 1])
        elif arg.startswith("-I") and len(arg) > 2:
            roots.append(arg[2:])
    return [os.path.normpath(os.path.join(directory, r)) for r in roots]


def reachable(roots):
    return {folder for root in roots for folder in FOLDERS if os.path.isdir(os.path.join(root, folder))}


def compiles(argv, directory, header):
    with tempfile.TemporaryDirectory() as scratch:
        probe = os.path.join(scratch, "probe.cpp")
        with open(probe, "w") as out:
            out.write(f'#include "{header}"\n')
        args = [argv[0], *include_flags(argv), "-std=c++20", "-fsyntax-only", probe]
        return subprocess.run(args, cwd=directory, capture_output=True, text=True).returncode == 0


def include_flags(argv):
    flags = []
    skip = False
    for i, arg in enumerate(argv):
        if skip:
            skip = False
            continue
        if arg in ("-I", "-isystem") and i + 1 < len(argv):
            flags += [arg, argv[i + 1]]
            skip = True
        elif arg.startswith(("-I", "-isystem", "-D")):
            flags.append(arg)
    return flags


NAMESPACE_OPENING = re.compile(r"^\s*namespace\s+([A-Za-z_][\w:]*)\s*\{", re.MULTILINE)


# The one file that defines a declaration of another layer: rcand's main sees the services only through
# kernel/service.hpp's linked_services(), which the services define.
NAMESPACE_EXCEPTIONS = {("services/linked_services.cpp", "rcand::kernel")}


def namespace_rule(path):
    """(allowed prefixes of a `rcand...` namespace, the module's own name) for a source file's repository path."""
    parts = path.split("/")
    if parts[0] == "libs":
        return ("rcand", f"rcand::{parts[1]}"), parts[1]
    if parts[0] == "services":
        own = parts[1] if len(parts) > 2 else "services"
        return ("rcand::services",) if own == "services" else ("rcand::services", f"rcand::services::{own}"), own
    if parts[0] == "sdk":
        return ("rcand::sdk",), "sdk"
    return (f"rcand::{parts[0]}",), parts[0]


def namespace_problems(source):
    files = []
    for top in ("libs", "kernel", "services", "rcanctl", "sdk/include/rcand/sdk"):
        for directory, _, names in os.walk(os.path.join(source, top)):
            files += [os.path.join(directory, n) for n in names if n.endswith((".hpp", ".cpp", ".h"))]
    modules = {"kernel", "services", "rcanctl", "sdk"} | set(os.listdir(os.path.join(source, "libs")))
    problems = []
    for file in sorted(files):
        path = os.path.relpath(file, source)
        allowed, own = namespace_rule(path)
        with open(file, encoding="utf-8", errors="replace") as f:
            text = f.read()
        for name in NAMESPACE_OPENING.findall(text):
            if (path, name) in NAMESPACE_EXCEPTIONS:
                continue
            if name == "rcand" or name.startswith("rcand::"):
                if not any(name == a or (a != "rcand" and name.startswith(a + "::")) for a in allowed):
                    problems.append(f"{path}: opens namespace {name}, must be in {' or '.join(allowed)}")
            elif name.split("::")[0] in modules - {own}:
                problems.append(f"{path}: opens namespace {name}, another module's")
    return problems, len(files)


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    source, build = (os.path.realpath(p) for p in sys.argv[1:])
    with open(os.path.join(build, "compile_commands.json")) as f:
        commands = json.load(f)
    problems, checked, probe_argv = [], {}, {}
    for command in commands:
        layer = layer_of(command, build)
        if layer is None:
            continue
        argv = command.get("arguments") or shlex.split(command["command"])
        roots = include_roots(argv, command["directory"])
        where = os.path.relpath(command["file"], build if command["file"].startswith(build) else source)
        if source in roots:
            problems.append(f"{where}: the source tree itself is an include root")
        seen = reachable(roots)
        if seen != ALLOWED[layer]:
            problems.append(f"{where} ({layer}/): reaches {sorted(seen)}, must reach {sorted(ALLOWED[layer])}")
        checked[layer] = checked.get(layer, 0) + 1
        probe_argv.setdefault(layer, (argv, command["directory"]))
    for layer in ALLOWED:
        if not checked.get(layer):
            problems.append(f"no compile of {layer}/ in compile_commands.json")
    # The compiler agrees: each layer compiles its own highest header and refuses the next layer's.
    for layer, own, foreign in (("libs", "libs", "kernel"), ("kernel", "kernel", "services"), ("rcanctl", "libs", "kernel")):
        if layer not in probe_argv:
            continue
        argv, directory = probe_argv[layer]
        if not compiles(argv, directory, PROBE_HEADERS[own]):
            problems.append(f"{layer}/: a probe including {PROBE_HEADERS[own]} does not compile with its flags")
        if compiles(argv, directory, PROBE_HEADERS[foreign]):
            problems.append(f"{layer}/: a probe including {PROBE_HEADERS[foreign]} compiles: the layering leaks")
    namespace_issues, sources = namespace_problems(source)
    problems += namespace_issues
    for problem in problems:
        print(problem)
    total = sum(checked.values())
    print(f"build layers: {total} compiles checked ({', '.join(f'{k} {v}' for k, v in sorted(checked.items()))}), "
          f"namespaces of {sources} sources, {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
