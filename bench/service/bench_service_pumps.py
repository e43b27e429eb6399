#!/usr/bin/env python3
"""Memory of `ambdiag serve` with many pumps registered (issue 16 benchmark).

  bench_service_pumps.py BUILD_DIR PLANT.json [N_PUMPS]

Starts a server on a fresh historian, registers N pumps (default 1000) with
the plant model over REST, and prints the server's resident memory before
and after, and the PUT rate. Figures go to docs/benchmarks.md."""
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import urllib.request


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        return int(re.search(r"VmRSS:\s+(\d+)", f.read()).group(1)) / 1024


def main():
    build, plant_path = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 1000
    cli = os.path.join(build, "cli", "ambdiag")
    tmp = tempfile.mkdtemp(prefix="bench_service_")
    db = os.path.join(tmp, "h.db")
    token = json.loads(subprocess.check_output([cli, "token", "add", "--db", db, "--role", "engineer", "--name", "b", "--json"]))["token"]
    env = dict(os.environ, CYCLONEDDS_URI="file://" + os.path.abspath(os.path.join(os.path.dirname(__file__), "../../deploy/cyclonedds/local.xml")))
    log = open(os.path.join(tmp, "server.log"), "w+")
    srv = subprocess.Popen([cli, "serve", "--db", db, "--http-port", "0", "--domain", "42", "--partition", "bench", "--quiet"],
                           stderr=log, env=env)
    port = None
    for _ in range(100):
        log.seek(0)
        m = re.search(r"REST on port (\d+)", log.read())
        if m:
            port = int(m.group(1))
            break
        time.sleep(0.1)
    try:
        time.sleep(1.0)
        before = rss_mb(srv.pid)
        plant = open(plant_path, "rb").read()
        t0 = time.time()
        for i in range(n):
            req = urllib.request.Request(f"http://127.0.0.1:{port}/api/v1/pumps/B-{i:05d}/model", data=plant, method="PUT",
                                         headers={"Authorization": "Bearer " + token, "Content-Type": "application/json"})
            urllib.request.urlopen(req).read()
        dt = time.time() - t0
        req = urllib.request.Request(f"http://127.0.0.1:{port}/api/v1/pumps", headers={"Authorization": "Bearer " + token})
        t1 = time.time()
        pumps = json.loads(urllib.request.urlopen(req).read())["pumps"]
        list_s = time.time() - t1
        time.sleep(1.0)
        after = rss_mb(srv.pid)
        print(f"pumps registered: {len(pumps)}; PUT model: {n / dt:.0f}/s; GET /pumps: {1000 * list_s:.0f} ms")
        print(f"server RSS: {before:.1f} MB before, {after:.1f} MB with {n} pumps registered")
    finally:
        srv.terminate()
        srv.wait()


if __name__ == "__main__":
    main()
