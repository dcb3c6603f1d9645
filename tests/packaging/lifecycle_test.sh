#!/usr/bin/env bash
# The packages' life on a clean Debian 12 root (issue 19): install, upgrade, remove, reinstall and purge rcand and
# its core plugins with apt in a debootstrap'ed minbase root, from a signed local APT repository made by
# packaging/make-apt-repo.sh (one sources.list line, as on a robot), checking what a robot builder relies on after each
# step - the service user and its groups, the JWT secret, the unit's enablement and mask, the admin's config edits,
# the state and log directories. The maintainer scripts run for real (dpkg, deb-systemd-helper, adduser); no
# systemd runs in the root, as in any image build. Then a vendor's plugin .deb is made in the same root from
# librcand-sdk-dev alone (its Depends must suffice for cpack).
#   tests/packaging/lifecycle_test.sh BUILD_DIR
# Needs root, debootstrap, cpack, dpkg-dev, apt-utils, gpg and a Debian mirror (RCAND_DEBIAN_MIRROR, default deb.debian.org). Where one is
# missing it exits 77 (ctest: skipped, saying why), unless RCAND_REQUIRE_LIFECYCLE=1 (CI), which makes that a failure.
set -euo pipefail
build=$(realpath "${1:?usage: lifecycle_test.sh BUILD_DIR}")
mirror=${RCAND_DEBIAN_MIRROR:-http://deb.debian.org/debian}

skip() {
  echo "SKIPPED: $*"
  [ "${RCAND_REQUIRE_LIFECYCLE:-0}" = 1 ] && { echo "RCAND_REQUIRE_LIFECYCLE=1: a skip is a failure"; exit 1; }
  exit 77
}
[ "$(id -u)" -eq 0 ] || skip "needs root (debootstrap and chroot)"
command -v debootstrap > /dev/null || skip "debootstrap is not installed"
command -v cpack > /dev/null || skip "cpack is not installed"
for tool in dpkg-scanpackages apt-ftparchive gpg; do
  command -v "$tool" > /dev/null || skip "$tool is not installed (dpkg-dev, apt-utils, gpg)"
done
repo_script=$(realpath "$(dirname "$0")/../../packaging/make-apt-repo.sh")

work=$(mktemp -d /tmp/rcand-lifecycle.XXXXXX)
root=$work/root
cleanup() { rm -rf --one-file-system "$work"; }
trap cleanup EXIT

failures=0
check() {  # check "what" command...: one line per check, the suite fails at the end if any failed
  local what=$1
  shift
  if "$@"; then echo "ok    $what"; else echo "FAIL  $what"; failures=$((failures + 1)); fi
}
in_root() { chroot "$root" "$@"; }
apt_in_root() { in_root env DEBIAN_FRONTEND=noninteractive apt-get -y -qq -o Dpkg::Options::=--force-confold "$@"; }
enabled_link=/etc/systemd/system/multi-user.target.wants/rcand.service
is_enabled() { [ "$(readlink "$root$enabled_link")" = /lib/systemd/system/rcand.service ]; }
is_masked() { [ "$(readlink "$root/etc/systemd/system/rcand.service")" = /dev/null ]; }
secret() { cat "$root/etc/rcand/jwt.secret"; }
# The robot's repository: REPO in the root, signed by a key made for this run; publish(DIR) adds DIR's packages.
repo=/srv/rcand
publish() {
  RCAND_REPO_GNUPGHOME=$work/gnupg "$repo_script" "$1" "$root$repo" > "$work/repo.log" 2>&1 || {
    cat "$work/repo.log"
    exit 1
  }
  in_root apt-get -qq update > "$work/apt.log" 2>&1 || {
    cat "$work/apt.log"
    exit 1
  }
}

echo "== packages (cpack) and a clean Debian 12 root (debootstrap, $mirror)"
cpack -G DEB --config "$build/CPackConfig.cmake" -B "$work/debs" > "$work/cpack.log" 2>&1 || {
  cat "$work/cpack.log"
  exit 1
}
debootstrap --variant=minbase bookworm "$root" "$mirror" > "$work/debootstrap.log" 2>&1 ||
  skip "debootstrap from $mirror failed: $(tail -n 2 "$work/debootstrap.log" | tr '\n' ' ')"
cp /etc/resolv.conf "$root/etc/resolv.conf"
# Every installed Debian system has one (systemd-machine-id-setup); rcand derives the robot's identity from it.
od -An -tx1 -N16 /dev/urandom | tr -d ' \n' > "$root/etc/machine-id"
mkdir -p "$work/v1" "$work/v2"
cp "$work"/debs/rcand_*.deb "$work"/debs/rcand-plugins-core_*.deb "$work/v1/"
# The upgrade: the same packages at a higher version (their Depends between each other follow the version).
version=$(dpkg-deb --field "$work"/v1/rcand_*.deb Version)
for deb in "$work"/v1/*.deb; do
  unpacked=$work/repack/$(basename "$deb" .deb)
  mkdir -p "$work/repack"
  dpkg-deb -R "$deb" "$unpacked"
  sed -i "s/^Version: .*/Version: ${version}+lifecycle1/" "$unpacked/DEBIAN/control"
  dpkg-deb --root-owner-group -b "$unpacked" "$work/v2/" > /dev/null
done
in_root apt-get -qq update > /dev/null
publish "$work/v1"
install -m 0644 "$root$repo/rcand-archive-keyring.gpg" "$root/usr/share/keyrings/rcand-archive-keyring.gpg"
echo "deb [signed-by=/usr/share/keyrings/rcand-archive-keyring.gpg] file:$repo ./" > "$root/etc/apt/sources.list.d/rcand.list"
in_root apt-get -qq update > /dev/null
check "the signed repository is trusted with its one sources.list line" \
  bash -c "chroot '$root' apt-cache policy rcand | grep -q 'file:$repo'"

echo "== install"
apt_in_root install --no-install-recommends rcand rcand-plugins-core > "$work/apt.log" 2>&1 || {
  cat "$work/apt.log"
  exit 1
}
check "rcand runs" in_root rcand --version
check "the rcand system user is in gpio, i2c, dialout and video" \
  bash -c "in_groups=\$(chroot '$root' id -nG rcand); for g in rcand gpio i2c dialout video; do [[ \" \$in_groups \" == *\" \$g \"* ]] || exit 1; done"
check "a JWT secret of 64 hex digits, root:rcand 0640" \
  bash -c "[[ \$(chroot '$root' stat -c '%U:%G %a' /etc/rcand/jwt.secret) == 'root:rcand 640' ]] && grep -qxE '[0-9a-f]{64}' '$root/etc/rcand/jwt.secret'"
check "/var/lib/rcand is rcand's, 0750" bash -c "[[ \$(chroot '$root' stat -c '%U:%G %a' /var/lib/rcand) == 'rcand:rcand 750' ]]"
check "the service is enabled (starts at boot)" is_enabled
check "the packaged config is valid for the rcand user" in_root runuser -u rcand -- rcand --check-config /etc/rcand/robot.rcan.yaml
first_secret=$(secret)
echo "# edited by the admin" >> "$root/etc/rcand/robot.rcan.yaml"
printf 'runtime:\n  logging:\n    level: debug\n' > "$root/etc/rcand/conf.d/50-site.yaml"
check "an admin's conf.d fragment is merged" \
  bash -c "chroot '$root' runuser -u rcand -- rcand --check-config /etc/rcand/robot.rcan.yaml 2>/dev/null | grep -qx '  merged /etc/rcand/conf.d/50-site.yaml'"
mkdir -p "$root/var/log/rcand" && echo "audit" > "$root/var/log/rcand/audit.jsonl"

echo "== upgrade to ${version}+lifecycle1 (published to the repository, then apt-get upgrade)"
publish "$work/v2"
apt_in_root upgrade > "$work/apt.log" 2>&1 || {
  cat "$work/apt.log"
  exit 1
}
check "upgraded" bash -c "chroot '$root' dpkg-query -W -f='\${Version}' rcand | grep -qx '${version}+lifecycle1'"
check "the admin's config edit is kept (a conffile)" grep -q "edited by the admin" "$root/etc/rcand/robot.rcan.yaml"
check "the JWT secret is unchanged" test "$(secret)" = "$first_secret"
check "the conf.d fragment is untouched" test -s "$root/etc/rcand/conf.d/50-site.yaml"
check "still enabled" is_enabled

echo "== remove"
apt_in_root remove rcand-plugins-core rcand > "$work/apt.log" 2>&1 || {
  cat "$work/apt.log"
  exit 1
}
check "the daemon is gone" test ! -e "$root/usr/sbin/rcand"
check "the config and the secret stay (remove is not purge)" test -s "$root/etc/rcand/robot.rcan.yaml" -a -s "$root/etc/rcand/jwt.secret"
check "the unit is masked while its package is removed" is_masked

echo "== reinstall"
apt_in_root install --no-install-recommends rcand rcand-plugins-core > "$work/apt.log" 2>&1 || {
  cat "$work/apt.log"
  exit 1
}
check "unmasked again" bash -c "! { [ -L '$root/etc/systemd/system/rcand.service' ] && [ \"\$(readlink '$root/etc/systemd/system/rcand.service')\" = /dev/null ]; }"
check "enabled again: the robot starts at boot" is_enabled
check "the same JWT secret (tokens issued before stay valid)" test "$(secret)" = "$first_secret"

echo "== purge"
apt_in_root purge rcand-plugins-core rcand > "$work/apt.log" 2>&1 || {
  cat "$work/apt.log"
  exit 1
}
check "/etc/rcand is gone but for the admin's own conf.d fragment (Debian leaves files it did not install)" \
  bash -c "[ \"\$(cd '$root/etc/rcand' && find . -type f)\" = ./conf.d/50-site.yaml ]"
check "state and logs are gone" test ! -e "$root/var/lib/rcand" -a ! -e "$root/var/log/rcand"
check "neither enabled nor masked" bash -c "[ ! -L '$root$enabled_link' ] && [ ! -L '$root/etc/systemd/system/rcand.service' ]"
check "no deb-systemd-helper state left" test ! -e "$root/var/lib/systemd/deb-systemd-helper-enabled/rcand.service.dsh-also"
check "dpkg knows nothing of rcand" bash -c "! chroot '$root' dpkg-query -W rcand > /dev/null 2>&1"

echo "== a vendor's plugin package, made in this root with librcand-sdk-dev (sdk/README.md's apt line, no Recommends)"
# librcand-sdk-dev's Depends must bring what packaging a scaffolded plugin runs (cpack: dpkg-shlibdeps, file). The
# unit test and lintian are left out here (vendor_loop_test runs both on the same template): a build of two sources
# keeps this step near a minute.
mkdir -p "$work/v3"
cp "$work"/debs/librcand-sdk-dev_*.deb "$work/v3/"
publish "$work/v3"
apt_in_root install --no-install-recommends librcand-sdk-dev rcand rcand-plugins-core doctest-dev cmake g++ ninja-build \
  > "$work/apt.log" 2>&1 || {
  cat "$work/apt.log"
  exit 1
}
check "librcand-sdk-dev brought dpkg-shlibdeps and file" in_root sh -c 'command -v dpkg-shlibdeps > /dev/null && command -v file > /dev/null'
vendor_build() {
  in_root sh -c 'cd /root && rcand-plugin new com.acme.lidar --kind capability > /dev/null &&
    cmake -S acme_lidar -B acme_lidar/build -G Ninja -DCMAKE_INSTALL_PREFIX=/usr -DBUILD_TESTING=OFF &&
    cmake --build acme_lidar/build && cpack --config acme_lidar/build/CPackConfig.cmake -B acme_lidar/debs' \
    > "$work/vendor.log" 2>&1 || {
    cat "$work/vendor.log"
    return 1
  }
}
check "rcand-plugin new, cmake and cpack make the plugin's .deb" vendor_build
vendor_deb=$(find "$root/root/acme_lidar/debs" -maxdepth 1 -name 'acme-lidar_*.deb' 2> /dev/null | head -n 1)
check "the .deb is there, with its copyright and changelog" \
  bash -c "dpkg-deb -c '$vendor_deb' | grep -q './usr/share/doc/acme-lidar/changelog.Debian.gz'"

echo "== a repository signed by another key"
mkdir -m 0700 "$work/other.gnupg"
GNUPGHOME=$work/other.gnupg gpg --batch --quiet --passphrase '' --quick-generate-key "someone else <x@rcand.invalid>" ed25519 sign never
GNUPGHOME=$work/other.gnupg gpg --batch --yes --clearsign --output "$root$repo/InRelease" "$root$repo/Release"
# apt keeps the lists it verified before and says why (for a repository it had, a warning: no exit code to check).
chroot "$root" apt-get update > "$work/apt.log" 2>&1 || true
check "apt refuses it (NO_PUBKEY: the lists are not updated)" grep -q "NO_PUBKEY" "$work/apt.log"

[ "$failures" -eq 0 ] || { echo "$failures check(s) failed"; exit 1; }
echo "all lifecycle checks passed"
