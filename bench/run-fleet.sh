#!/usr/bin/env bash
# Fleet benchmark (issue 31): N real rcand processes (the bundled sim robot, camera off, R2R over MQTT, each with its
# own name, Ed25519 key and loopback port) over two bridged mosquitto brokers: steady-state load at each fleet size,
# fleet e-stop -> last drive at zero, auctions and re-award, one broker down (bench/fleet_bench.py says how).
#   bench/run-fleet.sh [build-dir] [fleet_bench.py options, e.g. --sizes 50,100,200 --trials 20]
# Needs: rcand, the plugins sim_drive, teleop, nav, fleet, arm, chat, acme_gripper; mosquitto(_pub,_sub);
# python3 with yaml and cryptography. Bounded by --timeout (default 1500 s); cleans up after itself.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
[ $# -gt 0 ] && shift
echo "machine: $(nproc) cores, $(uptime)" >&2
exec python3 bench/fleet_bench.py --build "$build" "$@"
