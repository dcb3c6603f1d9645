#!/usr/bin/env bash
# The arm64 packages (Raspberry Pi 4/5, Jetson and other arm64 boards running Debian 12), cross-compiled on an amd64
# machine with Debian's cross toolchain and the arm64 multiarch libraries, then smoke-run under qemu-user:
# `rcand --version` and `rcand --check-plugins` of the arm64 build must pass.
#   packaging/build-arm64.sh [BUILD_DIR]     (default build-arm64; the .debs go to BUILD_DIR/debs)
# The build runs in its own Debian 12 root (BUILD_DIR/root, made with debootstrap on first use and kept): several
# arm64 -dev packages (yaml-cpp, OpenCV's imgcodecs and videoio) cannot be installed beside their amd64 twins, so
# cross-building in the machine's own root would remove the amd64 ones. Needs root, debootstrap, qemu-user-static
# and a Debian mirror (RCAND_DEBIAN_MIRROR, default deb.debian.org). Then `packaging/make-apt-repo.sh BUILD_DIR/debs
# REPO` makes a signed repository of them.
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath -m "${1:-build-arm64}")
mirror=${RCAND_DEBIAN_MIRROR:-http://deb.debian.org/debian}
root=$build/root
[ "$(id -u)" -eq 0 ] || { echo "build-arm64: needs root (debootstrap, chroot)" >&2; exit 1; }
for tool in debootstrap qemu-aarch64-static; do
  command -v "$tool" > /dev/null || { echo "build-arm64: $tool is missing (debootstrap, qemu-user-static)" >&2; exit 1; }
done
stage() { echo "== build-arm64: $1 (at ${SECONDS} s)"; }

if [ ! -e "$root/.rcand-build-root" ]; then
  stage "the build root (debootstrap, cross toolchain, arm64 libraries)"
  rm -rf --one-file-system "$root"
  mkdir -p "$build"
  debootstrap --variant=minbase bookworm "$root" "$mirror" > "$build/debootstrap.log" 2>&1 || {
    tail -n 20 "$build/debootstrap.log"
    exit 1
  }
  cp /etc/resolv.conf "$root/etc/resolv.conf"
  chroot "$root" dpkg --add-architecture arm64
  chroot "$root" apt-get -qq update
  # The libraries of packaging/install-deps.sh, for arm64 (nlohmann-json is header-only and architecture-free).
  chroot "$root" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    crossbuild-essential-arm64 cmake ninja-build pkg-config dpkg-dev file nlohmann-json3-dev libcli11-dev \
    libboost-dev:arm64 libyaml-cpp-dev:arm64 libspdlog-dev:arm64 libssl-dev:arm64 libavahi-client-dev:arm64 \
    libmosquitto-dev:arm64 libgpiod-dev:arm64 libopencv-core-dev:arm64 libopencv-imgproc-dev:arm64 \
    libopencv-imgcodecs-dev:arm64 libopencv-videoio-dev:arm64 libjpeg62-turbo-dev:arm64 libseccomp-dev:arm64 \
    > "$build/apt.log" 2>&1 || {
    tail -n 20 "$build/apt.log"
    exit 1
  }
  touch "$root/.rcand-build-root"
fi
# A root made before a dependency was added lacks it: CLI11 (rcanctl), libjpeg-turbo (the vision plugin's encoder),
# libseccomp (rcand-plugin-host's filter).
missing=()
[ -f "$root/usr/include/CLI/CLI.hpp" ] || missing+=(libcli11-dev)
[ -f "$root/usr/include/aarch64-linux-gnu/jconfig.h" ] || missing+=(libjpeg62-turbo-dev:arm64)
[ -f "$root/usr/lib/aarch64-linux-gnu/pkgconfig/libseccomp.pc" ] || missing+=(libseccomp-dev:arm64)
if [ ${#missing[@]} -gt 0 ]; then
  chroot "$root" apt-get -qq update
  chroot "$root" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" > /dev/null
fi

stage "the sources"
rm -rf "$root/src" && mkdir -p "$root/src"
tar --exclude='./build*' --exclude=./.git --exclude=./.cache -cf - . | tar -xf - -C "$root/src"

stage "cross build"
# What a package build needs: the daemon, plugins and rcanctl, unity sources, no tests (they would run on amd64).
chroot "$root" cmake -S /src -B /src/build -G Ninja -DCMAKE_TOOLCHAIN_FILE=/src/packaging/cross/aarch64-linux-gnu.cmake \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_INSTALL_PREFIX=/usr -DRCAND_BUILD_TESTS=OFF -DRCAND_BUILD_BENCH=OFF \
  -DCMAKE_UNITY_BUILD=ON > "$build/configure.log" 2>&1 || {
  cat "$build/configure.log"
  exit 1
}
chroot "$root" cmake --build /src/build
stage "packages"
chroot "$root" cpack -G DEB --config /src/build/CPackConfig.cmake -B /src/build/debs > "$build/cpack.log" 2>&1 || {
  cat "$build/cpack.log"
  exit 1
}
rm -rf "$build/debs" && mkdir -p "$build/debs"
cp "$root"/src/build/debs/*.deb "$root"/src/build/debs/*.ddeb "$build/debs/"

stage "smoke run under qemu-user"
# The arm64 loader and libraries come from the build root's multiarch directories (-L). Debian's alternatives (BLAS
# and LAPACK, which OpenCV links) are absolute links through /etc/alternatives, which the host resolves outside the
# root: the guest's loader is pointed at the directories they select in the root.
rcand=$root/src/build/kernel/rcand
file "$rcand" | grep -q "ARM aarch64" || { echo "$rcand is not an arm64 binary"; exit 1; }
alternatives=$(for link in "$root"/etc/alternatives/*-aarch64-linux-gnu; do
  if [ -L "$link" ]; then dirname "$(readlink "$link")"; fi
done | sort -u | paste -sd: -)
guest() { env LD_LIBRARY_PATH="$alternatives" qemu-aarch64-static -L "$root" "$@"; }
guest "$rcand" --version
guest "$rcand" --check-plugins --plugin-path "$root/src/build/plugins"
for deb in "$build"/debs/*.deb; do
  arch=$(dpkg-deb --field "$deb" Architecture)
  [ "$arch" = arm64 ] || [ "$arch" = all ] || { echo "$deb: Architecture $arch, not arm64"; exit 1; }
  echo "$(basename "$deb"): Depends: $(dpkg-deb --field "$deb" Depends)"
done
stage "arm64 packages in $build/debs"
