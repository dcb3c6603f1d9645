#!/usr/bin/env python3
"""rcan-py's `validate config` (the RCAN Python SDK's validator) still accepts rcand's bundled config (issue 30).

rcan-py is not on this machine's package index, so its validator runs from a checkout of continuonai/rcan-py: the
mirror's bare repository (RCAN_PY_GIT_DIR, default /work/.mirror/continuonai+rcan-py/repo) at the commit below. Only
rcan/validate.py and rcan/version.py are read (validate.py imports nothing else at load); the `rcan` package is set up
without its __init__.py, which imports the whole SDK and its optional dependencies. The canonical schema is not
fetched (no network in tests): the checks are validate_config's own (required keys, rcan_version, L1 identity).
Exit 77 (skipped) without the checkout or PyYAML.

Usage: rcan_py_validate.py CONFIG...
"""
import os
import subprocess
import sys
import tempfile
import types

COMMIT = "b184625efd8ca964ff7e5fd0a1e9ed7cad6e837a"
GIT_DIR = os.environ.get("RCAN_PY_GIT_DIR", "/work/.mirror/continuonai+rcan-py/repo")


def main(configs):
    if not os.path.isdir(GIT_DIR):
        print(f"skipped: no rcan-py checkout at {GIT_DIR}")
        return 77
    try:
        import yaml  # noqa: F401  (validate_config reads the file with it)
    except ImportError:
        print("skipped: PyYAML (python3-yaml) is not installed")
        return 77
    with tempfile.TemporaryDirectory() as root:
        package = os.path.join(root, "rcan")
        os.mkdir(package)
        for name in ("validate.py", "version.py"):
            source = subprocess.run(["git", f"--git-dir={GIT_DIR}", "show", f"{COMMIT}:rcan/{name}"], check=True,
                                    capture_output=True).stdout
            with open(os.path.join(package, name), "wb") as out:
                out.write(source)
        rcan = types.ModuleType("rcan")
        rcan.__path__ = [package]
        sys.modules["rcan"] = rcan
        sys.path.insert(0, root)
        from rcan.validate import validate_config

        failed = 0
        for config in configs:
            result = validate_config(config, fetch_schema=False)
            print(f"{config}: ok={result.ok} issues={result.issues} warnings={len(result.warnings)}")
            if not result.ok or result.issues:
                failed += 1
        return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
