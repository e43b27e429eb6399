#!/usr/bin/env bash
# The offline analysis with the command line (deploy/demo.sh runs the
# service): the reference pump (../shared/data/reference_pump): its modes,
# its simulated FRF matrix, the modes identified from a measurement and
# labelled against the model, the diagnosis of the dry run, a UFF58 export.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${AMBDIAG_DATA:-../shared/data}
out=${AMBDIAG_DEMO_OUT:-build/demo}

deploy/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j "${AMBDIAG_JOBS:-2}" --target ambdiag
mkdir -p "$out"
bin=build/cli/ambdiag
plant="$data/reference_pump/plant.json"

echo "== modes of the reference pump at its speed (ambdiag model modes)"
"$bin" model modes "$plant" --fmax 1000
"$bin" model modes "$plant" --fmax 1000 --json > "$out/modes.json"
echo
echo "== simulated 5 x 5 FRF matrix, 1..1000 Hz (ambdiag model frf)"
"$bin" model frf "$plant" -o "$out/model_frf.csv" --fmin 1 --fmax 1000 --df 1
echo
echo "== identified modes of a measurement, labelled against the model (ambdiag fit; Table 3 layout)"
"$bin" fit "$data/reference_pump/frf_ref_1.csv" --model "$plant" --svg "$out/stabilization.svg"
echo
echo "== diagnosis of a measurement against five healthy references (ambdiag diagnose; the paper's dry run)"
"$bin" diagnose --model "$plant" --reference "$data"/reference_pump/frf_ref_{1,2,3,4,5}.csv \
  --measured "$data/fault_dry_run/frf.csv" --svg "$out/diagnosis_dry_run.svg"
echo
echo "== export to Universal File Format 58 (ambdiag convert)"
"$bin" convert "$out/model_frf.csv" "$out/model_frf.uff"
echo
echo "outputs in $out/"
