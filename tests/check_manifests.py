#!/usr/bin/env python3
"""The manifests against manifests/manifest.schema.json, and their settings schemas against JSON Schema itself.

rcand's settings schemas are a subset of JSON Schema 2020-12 (sdk/include/rcand/sdk/contract/settings.hpp): each
manifest must pass manifest.schema.json, each settings schema must be a valid 2020-12 schema, and every example it
gives must pass a standard validator too (python3-jsonschema), not only rcand's. Exit 77 (skipped) without
python3-jsonschema.
"""
import glob
import json
import os
import sys

try:
    import jsonschema
except ImportError:
    print("python3-jsonschema is not installed: skipped")
    sys.exit(77)

root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
meta = json.load(open(os.path.join(root, "manifests", "manifest.schema.json")))
jsonschema.Draft202012Validator.check_schema(meta)
manifest_validator = jsonschema.Draft202012Validator(meta)
files = sorted(glob.glob(os.path.join(root, "manifests", "*.json"))) + [
    os.path.join(root, "plugins", "acme_gripper", "com.acme.gripper.json"),
    os.path.join(root, "tests", "unit", "core", "fixtures", "com.acme.tracks.json")]
failures = []
for path in files:
    if path.endswith("manifest.schema.json"):
        continue
    manifest = json.load(open(path))
    name = os.path.relpath(path, root)
    for error in manifest_validator.iter_errors(manifest):
        failures.append(f"{name}: {'/'.join(map(str, error.absolute_path))}: {error.message}")
    schemas = [("config", manifest["config"])] if "config" in manifest else []
    for item in manifest.get("provides", []):
        if "config" in item:
            schemas.append((f"provides {item['name']} config", item["config"]))
        for block, schema in item.get("reads", {}).items():
            schemas.append((f"provides {item['name']} reads {block}", schema))
    for where, schema in schemas:
        if schema.get("type") != "object":
            continue  # the older flat map is rcand's own form
        jsonschema.Draft202012Validator.check_schema(schema)
        validator = jsonschema.Draft202012Validator(schema)
        for example in schema.get("examples", []):
            example = {k: v for k, v in example.items() if k != "id"}  # a driver entry's own id
            for error in validator.iter_errors(example):
                failures.append(f"{name}: {where}: example {json.dumps(example)}: {error.message}")
for failure in failures:
    print(failure)
print(f"{len(files) - 1} manifests checked, {len(failures)} problem(s)")
sys.exit(1 if failures else 0)
