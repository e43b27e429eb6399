#!/usr/bin/env bash
# Runs the test suites and the numerics benchmarks of one build into a
# folder, so that two commits (before and after a change that must not
# change behaviour) can be compared with diff. Run it on an idle machine.
#   bench/run_numerics.sh BUILD_DIR OUT_DIR
set -uo pipefail
b=$(realpath "$1"); o=$2
mkdir -p "$o"; o=$(realpath "$o")
cd "$(dirname "$0")/.."
ninja -C "$b" -j2 > "$o/build.log" 2>&1 || { echo "build failed: $o/build.log"; exit 1; }
(cd "$b" && ctest -j2 -L fast --output-on-failure > "$o/fast.log" 2>&1; ctest -j2 -L slow --output-on-failure > "$o/slow.log" 2>&1)
for x in bench_explain bench_diagnosis; do /usr/bin/time -v "$b/bench/$x" > "$o/$x.out" 2> "$o/$x.err"; done
"$b/bench/bench_pump_frf" --basis krylov --reps 7 --loops 20 > "$o/bench_pump_frf.out" 2>&1
"$b/bench/bench_fit" > "$o/bench_fit.out" 2>&1
"$b/bench/bench_simulate" > "$o/bench_simulate.out" 2>&1
"$b/bench/bench_false_alarms" --pumps 4 --runs 28 --seed 1 > "$o/bench_false_alarms.out" 2>&1
"$b/bench/bench_model" --benchmark_filter=BM_ShaftFrfKrylov > "$o/bench_model.out" 2>&1
grep -h "tests passed" "$o"/fast.log "$o"/slow.log
