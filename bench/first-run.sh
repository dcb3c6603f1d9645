#!/usr/bin/env bash
# The README's first command on a fresh Debian 12 machine, timed (issue 19: ≤ 5 minutes on 2 cores, dependencies
# included): a minimal Debian 12 root (debootstrap minbase, git added, not timed) with a clone of this repository's
# HEAD, then inside it packaging/install-deps.sh, the configure, the build, and rcand on the bundled sim robot until
# it prints "listening on". Prints each part's seconds. Needs root, debootstrap and a Debian mirror
# (RCAND_DEBIAN_MIRROR); run it on an otherwise idle machine. Everything it makes is removed at exit.
#   bench/first-run.sh
set -euo pipefail
cd "$(dirname "$0")/.."
mirror=${RCAND_DEBIAN_MIRROR:-http://deb.debian.org/debian}
[ "$(id -u)" -eq 0 ] || { echo "first-run: needs root (debootstrap, chroot)" >&2; exit 1; }
command -v debootstrap > /dev/null || { echo "first-run: debootstrap is missing" >&2; exit 1; }
work=$(mktemp -d /var/tmp/rcand-first-run.XXXXXX)
root=$work/root
cleanup() {
  for mount in "$root/dev" "$root/proc"; do mountpoint -q "$mount" && umount "$mount"; done
  rm -rf --one-file-system "$work"
}
trap cleanup EXIT

echo "== first-run: a fresh Debian 12 root (not timed)"
debootstrap --variant=minbase bookworm "$root" "$mirror" > "$work/debootstrap.log" 2>&1 || {
  tail -n 20 "$work/debootstrap.log"
  exit 1
}
cp /etc/resolv.conf "$root/etc/resolv.conf"
mount -t proc proc "$root/proc"
mount --bind /dev "$root/dev"
chroot "$root" env DEBIAN_FRONTEND=noninteractive apt-get -qq update
chroot "$root" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends git ca-certificates > /dev/null
git clone -q . "$root/src"

echo "== first-run: the README's first command (timed)"
cat > "$root/first-run.sh" << 'INNER'
set -euo pipefail
cd /src
now() { date +%s.%N; }
seconds() { awk "BEGIN { printf \"%.1f\", $2 - $1 }"; }
start=$(now)
packaging/install-deps.sh > /tmp/deps.log
deps=$(now)
cmake -S . -B build -G Ninja > /tmp/configure.log
cmake --build build > /tmp/build.log
built=$(now)
build/kernel/rcand --config config/sim-rover.rcan.yaml > /tmp/rcand.out 2> /tmp/rcand.err &
pid=$!
until grep -q "listening on" /tmp/rcand.out; do
  kill -0 $pid 2> /dev/null || { cat /tmp/rcand.err; exit 1; }
  sleep 0.05
done
listening=$(now)
kill -INT $pid
wait $pid || true
echo "install-deps $(seconds $start $deps) s, configure + build $(seconds $deps $built) s ($(grep -c '^\[' /tmp/build.log) steps)," \
     "rcand listening $(seconds $built $listening) s after; total $(seconds $start $listening) s"
INNER
chroot "$root" bash /first-run.sh
