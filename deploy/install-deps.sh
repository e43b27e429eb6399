#!/usr/bin/env bash
# Installs every Debian package ambdiag needs to build, test and run.
# Idempotent: packages already present are skipped by apt; safe to run again.
set -euo pipefail

packages=(
  cmake g++ clang ninja-build pkg-config ccache git
  libeigen3-dev libsuitesparse-dev
  cyclonedds-dev cyclonedds-tools
  libsqlite3-dev sqlite3
  # The historian on PostgreSQL (issue 22): libpq to build; the server to
  # run the tests (they start a throwaway cluster of their own).
  libpq-dev postgresql
  nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcpp-httplib-dev zlib1g-dev
  libclang-rt-14-dev
  python3
  openssl libssl-dev
  # The security tests' loopback capture (issue 21); they skip without it.
  tcpdump
  prometheus  # promtool: the metrics test checks GET /metrics with it
  chromium    # the web UI's browser tests (headless, driven by playwright-core)
)
# Node.js (>= 18) and npm for the web UI and the test tools: Debian 12's
# nodejs 18 and npm 9 unless a node is installed already (e.g. NodeSource's,
# whose package replaces Debian's npm).
command -v node >/dev/null && command -v npm >/dev/null || packages+=(nodejs npm)
if command -v node >/dev/null && [ "$(node -p 'process.versions.node.split(".")[0]')" -lt 18 ]; then
  echo "install-deps: node $(node --version) is older than 18: the web UI's browser tests need 18 or later" >&2
fi

# npm packages the tests use, each folder pinned by its package-lock.json
# (npm ci installs exactly that); skipped when already installed from it.
npm_dirs=(tests/tools/openapi  # an independent OpenAPI validator
          web)                  # the web UI: uPlot, and playwright-core for its browser tests
install_npm() {
  local root
  root="$(cd "$(dirname "$0")/.." && pwd)"
  if ! command -v npm >/dev/null; then
    echo "install-deps: npm missing: the tests that need ${npm_dirs[*]} are skipped" >&2
    return 0
  fi
  for d in "${npm_dirs[@]}"; do
    if [ "$root/$d/node_modules/.package-lock.json" -nt "$root/$d/package-lock.json" ]; then continue; fi
    echo "install-deps: npm ci in $d" >&2
    npm ci --prefix "$root/$d" --no-audit --no-fund >&2
  done
}

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present" >&2
  install_npm
  exit 0
fi

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-deps: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
install_npm
