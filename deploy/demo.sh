#!/usr/bin/env bash
# Sets everything up on a fresh Debian 12 machine and runs the main job on the
# embedded default (SQLite): the analysis service. It starts `ambdiag serve`
# on a historian file, registers three pumps' plant models over REST, streams
# identification runs from three simulated pumps (`ambdiag-agent simulate`,
# each run at another speed and with seal coefficients drifting, as real pumps
# do; P-203's balance piston wears from its 4th run on), sets each pump's
# proposed reference (its first three runs), and prints per pump and run what
# the server concluded, read back over REST. The offline command-line demo is
# deploy/demo-offline.sh.
# Environment: AMBDIAG_DATA (shared data), AMBDIAG_DEMO_OUT (outputs),
# AMBDIAG_DEMO_RUNS (runs per pump, default 6), AMBDIAG_DOMAIN (DDS domain),
# AMBDIAG_DEMO_KEEP=1|0 (keep the server up for the web UI until Ctrl-C;
# default: when run from a terminal).
set -euo pipefail
cd "$(dirname "$0")/.."
data=${AMBDIAG_DATA:-../shared/data}
out=${AMBDIAG_DEMO_OUT:-build/demo}
runs=${AMBDIAG_DEMO_RUNS:-6}
domain=${AMBDIAG_DOMAIN:-17}

deploy/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j "${AMBDIAG_JOBS:-2}" --target ambdiag ambdiag-agent
bin=build/cli/ambdiag
agent=build/edge_agent/ambdiag-agent
plant="$data/reference_pump/plant.json"
export CYCLONEDDS_URI="file://$PWD/deploy/cyclonedds/local.xml"

mkdir -p "$out"
db="$out/historian.db"
rm -f "$db" "$db-wal" "$db-shm"
rm -rf "$out"/spool_*
token=$("$bin" token add --db "$db" --role engineer --name demo --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["token"])')

# --anonymous-read: the web UI opens on the demo fleet without a token (read-only);
# the engineer's token printed at the end signs in to acknowledge, shelve, explain.
: >"$out/server.log"  # read below at once: the background job may not have opened it yet
"$bin" serve --db "$db" --http-port 0 --domain "$domain" --partition demo --anonymous-read 2>"$out/server.log" &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null || true' EXIT
port=""
for _ in $(seq 100); do
  port=$(sed -n 's/.*REST on port \([0-9]*\).*/\1/p' "$out/server.log")
  [ -n "$port" ] && break
  sleep 0.1
done
[ -n "$port" ] || { cat "$out/server.log"; exit 1; }
url="http://127.0.0.1:$port"
echo "== ambdiag serve on $db, REST $url (log $out/server.log)"

echo "== three pumps registered with the reference pump's model (PUT /api/v1/pumps/{id}/model)"
deploy/demo/service_client.py "$url" "$token" register "$plant" P-201 P-202 P-203

echo "== $runs identification runs per pump streamed by simulated pumps (speed +-2 %, seal drift 1.5 %)"
pids=()
for p in P-201 P-202 P-203; do
  fault=()
  [ "$p" = P-203 ] && fault=(--fault "balance_piston_wear=1.3..1.6@run4..$runs")
  cat >"$out/agent_$p.json" <<JSON
{"schedule": {"identification_interval_s": 1, "monitoring_interval_s": 600, "runs": $runs}}
JSON
  "$agent" simulate --config "$out/agent_$p.json" --model "$plant" --pump "$p" --runs "$runs" \
    --speed-spread 2 --seal-drift 1.5 --seed "${p#P-}" "${fault[@]}" --fast \
    --domain "$domain" --partition demo --spool-dir "$out/spool_$p" 2>"$out/agent_$p.log" &
  pids+=($!)
done
for i in "${!pids[@]}"; do
  wait "${pids[$i]}" || { echo "agent $i failed:"; tail -5 "$out"/agent_*.log; exit 1; }
done
echo "   every run committed"

echo "== references set to the proposed first three runs; what the server concluded"
deploy/demo/service_client.py "$url" "$token" conclude P-201 P-202 P-203
echo
echo "outputs in $out/ (historian, logs); e.g. $url/api/v1/runs/{run_id}/bode.svg with the token"
# Interactive (a terminal), the server stays up for the browser until
# Ctrl-C; in scripts and CI it stops (AMBDIAG_DEMO_KEEP=1 / 0 forces either).
keep=${AMBDIAG_DEMO_KEEP:-}
[ -n "$keep" ] || { [ -t 0 ] && [ -t 1 ] && keep=1 || keep=0; }
if [ "$keep" = 1 ]; then
  echo "== the demo fleet in the web UI, read-only: $url/ (Sign in with the engineer's token $token to act); Ctrl-C stops the server"
  wait $server
else
  echo "== web UI: $url/ while the server runs (AMBDIAG_DEMO_KEEP=1 keeps it up; engineer's token $token)"
fi
