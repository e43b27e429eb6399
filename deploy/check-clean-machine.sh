#!/usr/bin/env bash
# Proves the README's test command on a clean Debian 12: a minimal bookworm
# root made by debootstrap, a fresh clone of this repository inside it, the
# shared material bind-mounted read-only beside it, then .ci/run as root.
# Needs root and network access to a Debian mirror. Usage:
#   deploy/check-clean-machine.sh [ROOT_DIR]   (default /var/tmp/ambdiag-clean)
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
shared="$(cd "$repo/../shared" && pwd)"
root="${1:-/var/tmp/ambdiag-clean}"
# A root left mounted by an interrupted run would let a later `rm -rf` reach
# the host's /dev through the bind mount: refuse until it is unmounted.
if findmnt -rn -o TARGET | grep -q "^$root/"; then
  echo "check-clean-machine: $root has mounts left from an earlier run; unmount them first:" >&2
  findmnt -rn -o TARGET | grep "^$root/" >&2
  exit 2
fi
command -v debootstrap >/dev/null || { apt-get update -q && apt-get install -y -q debootstrap; }
if [ ! -x "$root/bin/bash" ]; then
  debootstrap --variant=minbase bookworm "$root" http://deb.debian.org/debian
fi
cleanup() {
  for m in work/shared dev/pts dev proc; do mountpoint -q "$root/$m" && umount "$root/$m"; done
}
trap cleanup EXIT
mount -t proc proc "$root/proc"
mount --bind /dev "$root/dev"
mount --bind /dev/pts "$root/dev/pts"
mkdir -p "$root/work/shared"
mount --bind "$shared" "$root/work/shared"
mount -o remount,ro,bind "$root/work/shared"
cp /etc/resolv.conf "$root/etc/resolv.conf"
rm -rf "$root/work/main"
git clone -q "$repo" "$root/work/main"
echo "clean-machine check of $(git -C "$root/work/main" log --oneline -1)"
chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root \
  AMBDIAG_SANITIZE="${AMBDIAG_SANITIZE:-0}" AMBDIAG_TEST_SLOW="${AMBDIAG_TEST_SLOW:-0}" \
  /bin/bash -c "cd /work/main && ./.ci/run"
