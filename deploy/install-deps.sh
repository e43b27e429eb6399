#!/usr/bin/env bash
# Installs every Debian package ambdiag needs to build, test and run.
# Idempotent: packages already present are skipped by apt; safe to run again.
set -euo pipefail

packages=(
  cmake g++ clang ninja-build pkg-config ccache git
  libeigen3-dev libsuitesparse-dev
  cyclonedds-dev cyclonedds-tools
  libsqlite3-dev sqlite3
  nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcpp-httplib-dev
  libclang-rt-14-dev
  python3
  openssl libssl-dev
  # The security tests' loopback capture (issue 21); they skip without it.
  tcpdump
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present" >&2
  exit 0
fi

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-deps: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
