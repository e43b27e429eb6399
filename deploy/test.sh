#!/usr/bin/env bash
# Sets everything up on a fresh Debian 12 machine and runs all tests:
#   1. installs the Debian packages (deploy/install-deps.sh),
#   2. builds with warnings as errors and runs the default (`fast`) tests,
#   3. builds the file readers with clang + libFuzzer and fuzzes each briefly.
# Options (environment):
#   AMBDIAG_TEST_SLOW=1   also run the tests labelled `slow`
#   AMBDIAG_SANITIZE=1    also build and test under ASan + UBSan (build-asan/)
#   AMBDIAG_FUZZ_SECONDS  seconds per fuzz target (default 10)
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=${AMBDIAG_JOBS:-2}

deploy/install-deps.sh

start=$(date +%s)
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DAMBDIAG_WERROR=ON
cmake --build build -j "$jobs"
echo "test.sh: build took $(( $(date +%s) - start )) s" >&2

labels="fast"
[ "${AMBDIAG_TEST_SLOW:-0}" = 1 ] && labels="fast|slow"
ctest --test-dir build -L "$labels" --output-on-failure -j "$jobs"

# libFuzzer needs clang; only the format library and its fuzzers are built.
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DAMBDIAG_FUZZ=ON -DAMBDIAG_FUZZ_ONLY=ON -DAMBDIAG_BUILD_BENCH=OFF -DAMBDIAG_BUILD_TESTS=OFF \
  -DAMBDIAG_FUZZ_SECONDS="${AMBDIAG_FUZZ_SECONDS:-10}"
cmake --build build-fuzz -j "$jobs"
ctest --test-dir build-fuzz -L fuzz --output-on-failure

if [ "${AMBDIAG_SANITIZE:-0}" = 1 ]; then
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DAMBDIAG_SANITIZE=ON -DAMBDIAG_BUILD_BENCH=OFF
  cmake --build build-asan -j "$jobs"
  ctest --test-dir build-asan -L "$labels" --output-on-failure -j "$jobs"
fi
echo "test.sh: all tests passed" >&2
