#!/usr/bin/env bash
# Starts `ambdiag serve` and N agents on this machine over loopback DDS:
#   deploy/run-local.sh [N] [RUN_DIR]
# Each agent replays RUN_DIR (default the shared reference run) under its own
# pump and run id, as fast as possible. The server keeps running until
# Ctrl-C; its REST side is on $AMBDIAG_HTTP_PORT (default 8080).
# Environment: AMBDIAG_BUILD (build dir), AMBDIAG_DOMAIN (DDS domain, 0),
# AMBDIAG_OUT (folder for the database, spools and logs).
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-3}
run_dir=${2:-../shared/data/reference_pump/run_ref_1}
build=${AMBDIAG_BUILD:-build}
domain=${AMBDIAG_DOMAIN:-0}
port=${AMBDIAG_HTTP_PORT:-8080}
out=${AMBDIAG_OUT:-$build/run-local}
export CYCLONEDDS_URI="file://$PWD/deploy/cyclonedds/local.xml"

mkdir -p "$out"
"$build/cli/ambdiag" serve --db "$out/historian.db" --http-port "$port" --domain "$domain" 2>"$out/server.log" &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null' EXIT
echo "server pid $server, REST http://127.0.0.1:$port/api/v1/health, log $out/server.log" >&2

# Each agent streams a copy of the run under its own pump and run id.
python3 - "$run_dir" "$out" "$n" <<'PY'
import json, os, shutil, sys
src, out, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
meta = json.load(open(os.path.join(src, "run.json")))
for i in range(n):
    d = os.path.join(out, f"run_{i}")
    os.makedirs(d, exist_ok=True)
    m = dict(meta, pump_id=f"P-{i:03d}", run_id=f"P-{i:03d}/{meta['started_at']}")
    json.dump(m, open(os.path.join(d, "run.json"), "w"), indent=1)
    dst = os.path.join(d, "samples.f32")
    if not os.path.exists(dst):
        shutil.copyfile(os.path.join(src, "samples.f32"), dst)
PY

pids=()
for i in $(seq 0 $((n - 1))); do
  "$build/edge_agent/ambdiag-agent" replay "$out/run_$i" --fast --domain "$domain" \
    --partition site --spool-dir "$out/spool_$i" 2>"$out/agent_$i.log" &
  pids+=($!)
done
fail=0
for i in "${!pids[@]}"; do
  if wait "${pids[$i]}"; then echo "agent $i: run committed" >&2; else echo "agent $i: FAILED (see $out/agent_$i.log)" >&2; fail=1; fi
done
python3 -c "import urllib.request,sys; print(urllib.request.urlopen(sys.argv[1]).read().decode())" \
  "http://127.0.0.1:$port/api/v1/health" || true
echo >&2
if [ "${AMBDIAG_KEEP_SERVER:-0}" = 1 ]; then
  echo "server still running (Ctrl-C to stop)" >&2
  wait $server
fi
exit $fail
