#!/usr/bin/env bash
# Installs the Debian 12 packages rcand needs to build and test (only those: --no-install-recommends).
set -euo pipefail
packages=(
  cmake ninja-build g++ pkg-config         # build
  libboost-dev                              # Boost.Asio, Beast, DLL (header-only)
  nlohmann-json3-dev libyaml-cpp-dev libspdlog-dev libssl-dev
  doctest-dev                               # unit tests
  clang-14 libclang-rt-14-dev llvm-14       # the sanitizer + libFuzzer build of the tests (llvm-symbolizer)
  libavahi-client-dev                       # mDNS publish/resolve/browse (Avahi client over the system D-Bus)
  avahi-daemon avahi-utils dbus iproute2    # mDNS integration tests: private daemons in network namespaces
  libmosquitto-dev mosquitto mosquitto-clients  # R2R over MQTT; a real broker in the R2R tests
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopencv-videoio-dev  # the vision plugin
  curl                                      # README examples
  libgpiod-dev                              # the gpio H-bridge plugin (libgpiod 1.6 C API)
  chromium                                  # the dashboard test: headless Chromium driven by playwright-core
  prometheus                                # promtool: GET /metrics checked with `promtool check metrics`
  systemd                                   # systemd-analyze: the packaged unit's verify and security checks
  debootstrap                               # the packages' install/upgrade/remove/purge test in a clean root
)
# --checks: also what the test suite's code checks need (tests/check_kernel_shape.py, tests/check_style.sh).
if [ "${1:-}" = "--checks" ]; then
  packages+=(python3 git universal-ctags clang-format-14 clang-tidy-14)
fi
missing=()
for p in "${packages[@]}"; do dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p"); done
# Node.js and npm (they run playwright-core for the dashboard test): Debian's, unless a Node.js is already there (a
# NodeSource nodejs bundles npm and conflicts with Debian's npm package).
command -v npm > /dev/null || missing+=(nodejs npm)
[ ${#missing[@]} -eq 0 ] && exit 0
sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
