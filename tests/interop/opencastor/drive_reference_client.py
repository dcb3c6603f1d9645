#!/usr/bin/env python3
"""Drives rcand with the reference runtime's own client library (client.py, vendored unmodified).

Usage: drive_reference_client.py BASE_URL TOKEN
Prints one JSON object: for each call, {"ok": true, "answer": ...} or {"ok": false, "status": N, "body": ...}
(the CastorError the client raised). The C++ test (tests/integration/reference_client_test.cpp) judges it.
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from client import CastorClient, CastorError  # noqa: E402


def call(fn, *args, **kwargs):
    try:
        return {"ok": True, "answer": fn(*args, **kwargs)}
    except CastorError as e:
        return {"ok": False, "status": e.status, "body": e.body, "message": str(e)}


def main():
    base_url, token = sys.argv[1], sys.argv[2]
    results = {}
    with CastorClient(base_url, token=token, timeout=20) as client:
        results["health"] = call(client.health)
        results["status"] = call(client.status)
        results["action"] = call(client.action, type="move", linear=0.2, angular=0.0, duration_ms=200)
        results["command"] = call(client.command, "turn left 90 degrees")
        results["stop"] = call(client.stop)
        results["action_while_stopped"] = call(client.action, type="move", linear=0.2, angular=0.0)
        results["estop_clear"] = call(client.estop_clear)
        results["action_after_clear"] = call(client.action, type="stop")
        results["memory_episodes"] = call(client.memory_episodes)
    print(json.dumps(results))


if __name__ == "__main__":
    main()
