#!/usr/bin/env python3
"""GET /health and POST /api/stop (a clear between stops) on one kept-alive connection, with Python's stdlib client:
the same client against rcand and against the reference runtime (bench/run-stop-path.sh runs both).

  stop_vs_health.py PORT TOKEN [SAMPLES] [--clear-path PATH] [--no-auth-health]

Prints p50/p99 in ms for each, the stop repeated while latched, and the server's own latency_us when it reports one.
"""
import argparse
import http.client
import json
import statistics
import time


def percentile(values, p):
    ordered = sorted(values)
    return ordered[int(p * (len(ordered) - 1))]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("port", type=int)
    parser.add_argument("token")
    parser.add_argument("samples", type=int, nargs="?", default=500)
    parser.add_argument("--clear-path", default="/api/estop/clear")
    parser.add_argument("--stop-path", default="/api/stop")
    parser.add_argument("--health-path", default="/health")
    args = parser.parse_args()
    connection = http.client.HTTPConnection("127.0.0.1", args.port, timeout=5)
    headers = {"Authorization": "Bearer " + args.token, "Content-Type": "application/json"}

    def call(method, path, body=None):
        start = time.perf_counter()
        connection.request(method, path, body=body, headers=headers)
        response = connection.getresponse()
        data = response.read()
        elapsed_ms = (time.perf_counter() - start) * 1000
        if response.status != 200:
            raise SystemExit(f"{method} {path} answered {response.status}: {data[:300]!r}")
        return elapsed_ms, data

    for _ in range(50):  # warm-up: connection, caches, the servers' first-call paths
        call("GET", args.health_path)
        call("POST", args.stop_path, b"{}")
        call("POST", args.clear_path, b"{}")
    health, stop, repeated, server_us = [], [], [], []
    for _ in range(args.samples):
        health.append(call("GET", args.health_path)[0])
    for _ in range(args.samples):
        elapsed, data = call("POST", args.stop_path, b"{}")
        stop.append(elapsed)
        try:
            latency = json.loads(data).get("latency_us")
            if isinstance(latency, (int, float)):
                server_us.append(latency)
        except ValueError:
            pass
        call("POST", args.clear_path, b"{}")
    call("POST", args.stop_path, b"{}")
    for _ in range(args.samples):
        repeated.append(call("POST", args.stop_path, b"{}")[0])
    call("POST", args.clear_path, b"{}")

    def line(name, values, unit="ms"):
        print(f"{name:<38} p50 {percentile(values, 0.5):8.3f}  p99 {percentile(values, 0.99):8.3f}  "
              f"mean {statistics.fmean(values):8.3f} {unit}")

    print(f"samples {args.samples}, one kept-alive connection (Python {http.client.__name__})")
    line("GET /health", health)
    line("POST /api/stop (+ clear between)", stop)
    line("POST /api/stop repeated while latched", repeated)
    if server_us:
        line("server latency_us (latch -> halted)", server_us, "us")


if __name__ == "__main__":
    main()
