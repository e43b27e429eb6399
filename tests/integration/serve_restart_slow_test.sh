#!/usr/bin/env bash
# ambdiag serve started at a random moment (0-0.5 s) before `pg_ctl
# restart -m immediate` of its PostgreSQL must ride the restart out, N times
# (ctest serve_restart_slow_test; docs/storage.md "Opening"). Allowed: a
# first connection that finds no socket (the server is down: it exits
# naming the location, by design) and nothing else.
#   serve_restart_slow_test.sh BUILD_DIR [N]
set -euo pipefail
if [ "${AMBDIAG_NO_POSTGRES:-}" = 1 ]; then echo "AMBDIAG_NO_POSTGRES=1: skipped"; exit 77; fi
build=$1
n=${2:-20}
dir=$(mktemp -d /tmp/ambdiag-pg-restart.XXXXXX)
chmod 755 "$dir"  # as root, PostgreSQL runs as postgres and must reach DIR/pg
pg="$dir/pg"
trap '"$build/tests/ambdiag-test-pg" stop "$pg" >/dev/null 2>&1 || true; rm -rf "$dir"' EXIT
"$build/tests/ambdiag-test-pg" start "$pg" >/dev/null
uri="postgresql:///postgres?host=$pg&port=5432&user=postgres"
"$build/cli/ambdiag" token list --db "$uri" >/dev/null  # the schema, once
died=0 no_socket=0
for i in $(seq 1 "$n"); do
  "$build/cli/ambdiag" serve --db "$uri" --http-port 0 --domain $((100 + $$ % 100)) --partition "restart-$$-$i" \
    --instance "R$i" >"$dir/serve_$i.log" 2>&1 &
  pid=$!
  sleep "0.$((RANDOM % 6))"
  "$build/tests/ambdiag-test-pg" restart "$pg" immediate
  sleep 3
  if kill -0 "$pid" 2>/dev/null; then
    kill "$pid"; wait "$pid" 2>/dev/null || true
  elif grep -q "No such file or directory" "$dir/serve_$i.log"; then
    no_socket=$((no_socket + 1))
  else
    echo "start $i: the server died during the restart:" >&2; cat "$dir/serve_$i.log" >&2
    died=$((died + 1))
  fi
done
echo "$n starts across a restart: $((n - died - no_socket)) rode it out, $no_socket found no socket (by design), $died died"
[ "$died" = 0 ]
