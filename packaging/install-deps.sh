#!/usr/bin/env bash
# Installs the Debian 12 packages rcand needs (only those: --no-install-recommends).
#   packaging/install-deps.sh            to build and run rcand, its plugins and rcanctl (the README's first command)
#   packaging/install-deps.sh --tests    also what the test suite runs against (compilers for the sanitizer build,
#                                        brokers, daemons, a browser, promtool, debootstrap)
#   packaging/install-deps.sh --checks   --tests and the code checks (tests/check_kernel_shape.py, check_style.sh)
set -euo pipefail
packages=(
  cmake ninja-build g++ pkg-config         # build
  libboost-dev                              # Boost.Asio, Beast, DLL (header-only)
  nlohmann-json3-dev libyaml-cpp-dev libspdlog-dev libssl-dev
  libcli11-dev                              # rcanctl's command lines (CLI11, header-only)
  libavahi-client-dev                       # mDNS publish/resolve/browse (Avahi client over the system D-Bus)
  libmosquitto-dev                          # R2R over MQTT
  libopencv-core-dev libopencv-imgproc-dev libopencv-videoio-dev  # the vision plugin (videoio: its video module)
  libjpeg62-turbo-dev libopencv-imgcodecs-dev  # its JPEG encoder; imgcodecs: its tests decode with it
  libgpiod-dev                              # the gpio H-bridge plugin (libgpiod 1.6 C API)
  libseccomp-dev                            # rcand-plugin-host's system call filter (isolation: process)
  curl                                      # README examples
)
case "${1:-}" in --tests | --checks) tests=1 ;; *) tests=0 ;; esac
if [ "$tests" = 1 ]; then
  packages+=(
    doctest-dev                               # unit tests
    clang-14 libclang-rt-14-dev llvm-14       # the sanitizer + libFuzzer build of the tests (llvm-symbolizer)
    avahi-daemon avahi-utils dbus iproute2    # mDNS integration tests: private daemons in network namespaces
    mosquitto mosquitto-clients               # a real broker in the R2R tests
    chromium                                  # the dashboard test: headless Chromium driven by playwright-core
    prometheus                                # promtool: GET /metrics checked with `promtool check metrics`
    systemd                                   # systemd-analyze: the packaged unit's verify and security checks
    debootstrap dpkg-dev apt-utils gpg file   # the packages' lifecycle test in a clean root, from a signed repository
    lintian                                   # the packages and a vendor plugin's .deb: no lintian errors
    qemu-user-static                          # the arm64 packages' smoke run (packaging/build-arm64.sh)
    openssl                                   # the TLS tests' throwaway CA and certificates (tests/support/tls_lab.hpp)
    python3-jsonschema                        # the manifests against JSON Schema (tests/check_manifests.py)
    python3-yaml                              # rcan-py's validator on the bundled config (tests/rcan_py_validate.py)
  )
fi
if [ "${1:-}" = "--checks" ]; then
  packages+=(python3 git universal-ctags clang-format-14 clang-tidy-14)
fi
missing=()
for p in "${packages[@]}"; do dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p"); done
# Node.js and npm (they run playwright-core for the dashboard test): Debian's, unless a Node.js is already there (a
# NodeSource nodejs bundles npm and conflicts with Debian's npm package).
[ "$tests" = 0 ] || command -v npm > /dev/null || missing+=(nodejs npm)
[ ${#missing[@]} -eq 0 ] && exit 0
sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
