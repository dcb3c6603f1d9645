#!/usr/bin/env python3
"""The reference runtime's API gateway (craigm26/OpenCastor `castor.api`) run from a source checkout with what Debian 12
packages, for bench/run-stop-path.sh; nothing on a request's path is changed.

  reference_gateway.py CHECKOUT PORT          (OPENCASTOR_CONFIG and OPENCASTOR_API_TOKEN as the gateway reads them)

Three gaps between a pip install of its pyproject (no network here) and Debian's packages are bridged, each said on
stderr when it applies:
- the checkout is not installed, so `importlib.metadata.version("opencastor")` (read at import) has no metadata:
  the version of its pyproject.toml is written as the metadata pip would write;
- FastAPI before 0.93 ignores `lifespan=` (Debian 12: 0.92): the gateway's own on_startup/on_shutdown are registered
  as startup and shutdown handlers instead, so its config, virtual filesystem, brain and driver come up as they would;
- the brain of its example config is Anthropic's, whose SDK is not packaged: a stand-in client class (no call is
  made: the bench only stops, clears and asks /health).
"""
import importlib.metadata
import pathlib
import re
import sys
import tempfile
import types


def say(text):
    print(f"reference_gateway: {text}", file=sys.stderr)


def provide_package_metadata(checkout, site):
    try:
        importlib.metadata.version("opencastor")
        return
    except importlib.metadata.PackageNotFoundError:
        pass
    version = re.search(r'^version\s*=\s*"([^"]+)"', (checkout / "pyproject.toml").read_text(), re.M).group(1)
    info = site / f"opencastor-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: opencastor\nVersion: {version}\n")
    sys.path.append(str(site))
    say(f"not installed: package metadata for opencastor {version} written to a temporary directory")


def provide_anthropic_stand_in():
    try:
        import anthropic  # noqa: F401
    except ImportError:
        module = types.ModuleType("anthropic")
        module.Anthropic = type("Anthropic", (), {"__init__": lambda self, **kwargs: None})
        sys.modules["anthropic"] = module
        say("no anthropic SDK: a stand-in client class for the example config's brain")


def main():
    checkout, port = pathlib.Path(sys.argv[1]).resolve(), int(sys.argv[2])
    sys.path.insert(0, str(checkout))
    metadata = tempfile.TemporaryDirectory(prefix="opencastor-metadata-")  # removed when the server returns
    provide_package_metadata(checkout, pathlib.Path(metadata.name))
    provide_anthropic_stand_in()
    import fastapi
    import uvicorn

    from castor import api

    if tuple(int(part) for part in fastapi.__version__.split(".")[:2]) < (0, 93):
        api.app.router.on_startup.append(api.on_startup)
        api.app.router.on_shutdown.append(api.on_shutdown)
        say(f"FastAPI {fastapi.__version__} ignores lifespan=: the gateway's startup and shutdown registered as handlers")
    say(f"FastAPI {fastapi.__version__}, uvicorn {uvicorn.__version__}, Python {sys.version.split()[0]}")
    with metadata:
        uvicorn.run(api.app, host="127.0.0.1", port=port, log_level="warning")


if __name__ == "__main__":
    main()
