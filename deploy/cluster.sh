#!/usr/bin/env bash
# A local cluster on this machine (issue 22, docs/deployment.md "A local
# cluster"): a PostgreSQL server of its own (initdb/pg_ctl in a folder, on a
# Unix socket only; as root it runs as the `postgres` user, which refuses
# root), three `ambdiag serve` processes on its database in one ingest group
# (s1 and s2: ingest, analysis, REST; s3: analysis and REST), and N simulated
# pumps (`ambdiag-agent simulate`, paced identification runs back to back).
#   deploy/cluster.sh [start] [--agents N] [--runs R] [--dir DIR]
#   deploy/cluster.sh status [--dir DIR]
#   deploy/cluster.sh stop [--dir DIR]
# start prints the REST / web UI addresses and an engineer's token (also in
# DIR/cluster.env) and returns; the processes run until `stop`.
# Options: --agents N (default 3), --runs R identification runs per agent
# (default 0: until stopped), --dir DIR (default $AMBDIAG_BUILD/cluster).
# Environment: AMBDIAG_BUILD (build dir, default build), AMBDIAG_DATA
# (shared data, default ../shared/data), AMBDIAG_DOMAIN (DDS domain, default
# 23), AMBDIAG_CLUSTER_PORT (first REST port; default 0: any free ones).
set -euo pipefail
cd "$(dirname "$0")/.."
cmd=start
case "${1:-}" in start | stop | status) cmd=$1; shift ;; esac
agents=3
runs=0
build=${AMBDIAG_BUILD:-build}
dir=""
while [ $# -gt 0 ]; do
  case "$1" in
    --agents) agents=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --dir) dir=$2; shift 2 ;;
    *) echo "deploy/cluster.sh: unknown option $1 (start|stop|status [--agents N] [--runs R] [--dir DIR])" >&2; exit 2 ;;
  esac
done
[[ "$agents" =~ ^[0-9]+$ ]] || { echo "deploy/cluster.sh: --agents must be a number" >&2; exit 2; }
[[ "$runs" =~ ^[0-9]+$ ]] || { echo "deploy/cluster.sh: --runs must be a number" >&2; exit 2; }
dir=${dir:-$build/cluster}
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
data=${AMBDIAG_DATA:-../shared/data}
domain=${AMBDIAG_DOMAIN:-23}
first_port=${AMBDIAG_CLUSTER_PORT:-0}
bin=$build/cli/ambdiag
agent=$build/edge_agent/ambdiag-agent
pids="$dir/pids"  # "name pid" per line, servers and agents
# The socket's path must be short (about 100 bytes): a folder under /tmp named after DIR.
sock=/tmp/ambdiag-cluster-$(printf '%s' "$dir" | cksum | cut -d' ' -f1)
uri="postgresql:///postgres?host=$sock&port=5432&user=postgres"

pg_bin() {
  local d
  d=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)
  if [ -n "$d" ] && [ -x "$d/pg_ctl" ]; then echo "$d"; return; fi
  command -v pg_ctl >/dev/null && { dirname "$(command -v pg_ctl)"; return; }
  echo "deploy/cluster.sh: PostgreSQL is not installed (no pg_ctl): run deploy/install-deps.sh" >&2
  exit 1
}
as_pg() {  # PostgreSQL's programs refuse to run as root
  if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}
alive() { kill -0 "$1" 2>/dev/null; }

stop_all() {
  if [ -f "$pids" ]; then
    # Agents first (their spools keep what was not acknowledged), then servers.
    for kind in agent server; do
      while read -r name pid; do
        [[ "$name" == "$kind"* ]] && alive "$pid" && kill "$pid" 2>/dev/null || true
      done <"$pids"
      for _ in $(seq 100); do
        left=0
        while read -r name pid; do [[ "$name" == "$kind"* ]] && alive "$pid" && left=1 || true; done <"$pids"
        [ $left = 0 ] && break
        sleep 0.2
      done
      while read -r name pid; do
        if [[ "$name" == "$kind"* ]] && alive "$pid"; then
          echo "$name ($pid) did not stop: killed" >&2
          kill -9 "$pid" 2>/dev/null || true
        fi
      done <"$pids"
    done
    rm -f "$pids"
  fi
  if [ -f "$dir/pg/data/postmaster.pid" ]; then
    as_pg "$(pg_bin)/pg_ctl" -D "$dir/pg/data" -m fast -w stop >/dev/null || true
  fi
  rm -rf "$sock"
  echo "cluster in $dir stopped"
}

status() {
  [ -f "$pids" ] || { echo "no cluster running in $dir"; return 1; }
  [ -f "$dir/cluster.env" ] && cat "$dir/cluster.env"
  local bad=0
  while read -r name pid; do
    # An agent with --runs R ends when its runs are done; a server never should.
    if alive "$pid"; then state=running; elif [[ "$name" == agent* ]]; then state=ended; else state=DEAD; bad=1; fi
    line="$name pid $pid $state"
    if [[ "$name" == server* ]] && [ -f "$dir/$name.port" ]; then
      line+=" $(python3 - "$(cat "$dir/$name.port")" <<'PY'
import json, sys, urllib.request
try:
    h = json.load(urllib.request.urlopen(f"http://127.0.0.1:{sys.argv[1]}/api/v1/health", timeout=2))
    g = (h.get("ingest_groups") or [{}])[0]
    print("parts", ",".join(h.get("parts", [])), "ingest", g.get("role", "-"), "runs", (h.get("ingest") or {}).get("runs_complete", "-"))
except Exception as e:
    print("health:", e)
PY
)"
    fi
    echo "$line"
  done <"$pids"
  return $bad
}

case $cmd in
  stop) stop_all; exit 0 ;;
  status) status; exit $? ;;
esac

[ -x "$bin" ] && [ -x "$agent" ] || { echo "deploy/cluster.sh: build ambdiag and ambdiag-agent first ($build/cli/ambdiag, $build/edge_agent/ambdiag-agent; AMBDIAG_BUILD)" >&2; exit 1; }
if [ -f "$pids" ]; then echo "deploy/cluster.sh: a cluster runs in $dir (deploy/cluster.sh stop --dir $dir)" >&2; exit 1; fi
export CYCLONEDDS_URI="file://$PWD/deploy/cyclonedds/local.xml"
plant="$data/reference_pump/plant.json"
[ -f "$plant" ] || { echo "deploy/cluster.sh: no $plant (AMBDIAG_DATA)" >&2; exit 1; }
trap 'echo "deploy/cluster.sh: start failed, stopping what started" >&2; stop_all' ERR

# PostgreSQL: created at the first start, kept across stop/start (durable, fsync on).
pgb=$(pg_bin)
mkdir -p "$dir/pg" "$sock"
if [ "$(id -u)" = 0 ]; then chown postgres: "$dir/pg" "$sock"; fi
chmod 700 "$dir/pg"
if [ ! -f "$dir/pg/data/PG_VERSION" ]; then
  as_pg "$pgb/initdb" -D "$dir/pg/data" --auth=trust --username=postgres --encoding=UTF8 --locale=C.UTF-8 >"$dir/pg/initdb.log"
fi
as_pg "$pgb/pg_ctl" -D "$dir/pg/data" -l "$dir/pg/log" -w -t 60 \
  -o "-c listen_addresses='' -c unix_socket_directories=$sock -p 5432 -c max_connections=200" start >/dev/null
token=$("$bin" token add --db "$uri" --role engineer --name "cluster-$(date +%s)" --json |
  python3 -c 'import json,sys; print(json.load(sys.stdin)["token"])')

: >"$pids"
start_server() {  # name parts port
  local name=$1 parts=$2 port=$3 extra=()
  [[ "$parts" == *ingest* ]] && extra+=(--domain "$domain" --partition cluster --ingest-group cluster)
  : >"$dir/$name.log"  # read below at once: the background job may not have opened it yet
  setsid "$bin" serve --db "$uri" --parts "$parts" --instance "$name" --http-port "$port" --anonymous-read \
    "${extra[@]}" >"$dir/$name.log" 2>&1 </dev/null &
  echo "server-$name $!" >>"$pids"
  for _ in $(seq 200); do
    p=$(sed -n 's/.*REST on port \([0-9]*\).*/\1/p' "$dir/$name.log")
    [ -n "$p" ] && { echo "$p" >"$dir/server-$name.port"; return; }
    alive "$!" || break
    sleep 0.1
  done
  echo "deploy/cluster.sh: server $name did not start:" >&2
  cat "$dir/$name.log" >&2
  return 1
}
port_of() { [ "$first_port" = 0 ] && echo 0 || echo $((first_port + $1)); }
start_server s1 ingest,analysis,rest "$(port_of 0)"
start_server s2 ingest,analysis,rest "$(port_of 1)"
start_server s3 analysis,rest "$(port_of 2)"
p1=$(cat "$dir/server-s1.port")

# Each pump: the shared reference pump's model, then its agent (paced runs
# of 7.5 s, one after the other; a spool each).
cat >"$dir/agent.json" <<JSON
{"schedule": {"identification_interval_s": 0.1, "monitoring_interval_s": 0, "runs": $runs},
 "simulation": {"period_samples": 1024, "f_min_hz": 2, "settle_periods": 1, "meas_periods": 2}}
JSON
for i in $(seq 1 "$agents"); do
  pump=$(printf 'C-%03d' "$i")
  python3 - "http://127.0.0.1:$p1/api/v1/pumps/$pump/model" "$token" "$plant" <<'PY'
import sys, urllib.request
req = urllib.request.Request(sys.argv[1], data=open(sys.argv[3], "rb").read(), method="PUT",
                             headers={"Authorization": "Bearer " + sys.argv[2], "Content-Type": "application/json"})
urllib.request.urlopen(req, timeout=30).read()
PY
  setsid "$agent" simulate --config "$dir/agent.json" --model "$plant" --pump "$pump" --runs "$runs" \
    --speed-spread 1 --seal-drift 1 --seed "$i" --domain "$domain" --partition cluster \
    --spool-dir "$dir/spool_$pump" >"$dir/agent_$pump.log" 2>&1 </dev/null &
  echo "agent-$pump $!" >>"$pids"
done
trap - ERR
{
  echo "PostgreSQL: $uri (log $dir/pg/log)"
  for s in s1 s2 s3; do echo "server $s: REST and web UI http://127.0.0.1:$(cat "$dir/server-$s.port")/ (log $dir/$s.log)"; done
  echo "engineer token: $token"
  echo "agents: $agents simulated pumps C-001.., $([ "$runs" = 0 ] && echo "until stopped" || echo "$runs runs each")"
} | tee "$dir/cluster.env"
echo "deploy/cluster.sh status --dir $dir / deploy/cluster.sh stop --dir $dir"
