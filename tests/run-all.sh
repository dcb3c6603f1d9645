#!/usr/bin/env bash
# The whole test suite: installs dependencies, builds with Ninja, runs every test (units, fixture plugins,
# integration tests with real rcand processes). Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
packaging/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo > /dev/null
cmake --build build
ctest --test-dir build --output-on-failure --timeout 600
