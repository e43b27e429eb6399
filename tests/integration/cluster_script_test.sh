#!/usr/bin/env bash
# deploy/cluster.sh as a user runs it (ctest cluster_script_test): a local
# cluster with two simulated pumps of two runs each; their runs arrive and
# are analysed, as REST on two different servers says (s1 ingests, s3 only
# analyses and serves); then `stop` leaves no process of it running.
#   cluster_script_test.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
if [ "${AMBDIAG_NO_POSTGRES:-}" = 1 ]; then echo "AMBDIAG_NO_POSTGRES=1: skipped"; exit 77; fi
src=$1
build=$2
dir=$(mktemp -d /tmp/ambdiag-cluster-test.XXXXXX)
chmod 755 "$dir"  # as root, PostgreSQL runs as postgres and must reach DIR/pg
export AMBDIAG_BUILD=$build AMBDIAG_DOMAIN=$((100 + $$ % 120))
cleanup() { "$src/deploy/cluster.sh" stop --dir "$dir" >/dev/null 2>&1 || true; rm -rf "$dir"; }
trap cleanup EXIT
"$src/deploy/cluster.sh" start --agents 2 --runs 2 --dir "$dir"
token=$(sed -n 's/^engineer token: //p' "$dir/cluster.env")
s1=$(cat "$dir/server-s1.port")
s3=$(cat "$dir/server-s3.port")
# Every run of both pumps listed on s1, each analysed as s3 says (done or failed).
python3 - "$s1" "$s3" "$token" <<'PY'
import json, sys, time, urllib.parse, urllib.request
s1, s3, token = sys.argv[1:4]
def get(port, path):
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", headers={"Authorization": "Bearer " + token})
    return json.load(urllib.request.urlopen(req, timeout=10))
deadline = time.time() + 150
while True:
    runs = [r for p in ("C-001", "C-002") for r in get(s1, f"/api/v1/pumps/{p}/runs")["runs"]]
    complete = [r["run_id"] for r in runs if r.get("status") == "complete"]
    states = {rid: get(s3, "/api/v1/runs/" + urllib.parse.quote(rid, safe="") + "/analysis")["status"] for rid in complete}
    if len(complete) == 4 and all(s in ("done", "failed") for s in states.values()):
        break
    if time.time() > deadline:
        sys.exit(f"not every run arrived and was analysed in time: {states}")
    time.sleep(1)
print("4 runs arrived (s1) and were analysed (s3):", states)
if not any(s == "done" for s in states.values()):
    sys.exit("no analysis succeeded")
PY
"$src/deploy/cluster.sh" status --dir "$dir"
pids=$(awk '{print $2}' "$dir/pids")
postmaster=$(head -1 "$dir/pg/data/postmaster.pid")
"$src/deploy/cluster.sh" stop --dir "$dir"
for p in $pids $postmaster; do
  # A zombie (exited, not yet reaped: here pid 1 may never reap) runs nothing.
  state=$(ps -o stat= -p "$p" 2>/dev/null || true)
  if [ -n "$state" ] && [[ "$state" != Z* ]]; then echo "process $p still runs after stop ($state)" >&2; exit 1; fi
done
[ ! -e "$dir/pids" ] || { echo "stop left $dir/pids" >&2; exit 1; }
echo "cluster stopped: nothing left running"
