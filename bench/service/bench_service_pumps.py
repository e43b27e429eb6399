#!/usr/bin/env python3
"""Memory of `ambdiag serve` with many pumps registered (issue 16 benchmark).

  bench_service_pumps.py BUILD_DIR PLANT.json [N_PUMPS]

Starts a server on a fresh historian, registers N pumps (default 1000) with
the plant model over REST, times GET /api/v1/pumps and GET /api/v1/fleet
(the web UI's fleet view), and prints the server's resident memory before
and after, and the PUT rate. Figures go to docs/benchmarks.md."""
import re
import sys
import time

from bench_server import BenchServer


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        return int(re.search(r"VmRSS:\s+(\d+)", f.read()).group(1)) / 1024


def main():
    build, plant_path = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 1000
    srv = BenchServer(build, "bench_service_", "42", "bench", ["--quiet"])
    try:
        time.sleep(1.0)
        before = rss_mb(srv.proc.pid)
        plant = open(plant_path, "rb").read()
        t0 = time.time()
        for i in range(n):
            srv.call("PUT", f"/api/v1/pumps/B-{i:05d}/model", plant)
        dt = time.time() - t0
        t1 = time.time()
        pumps = srv.call("GET", "/api/v1/pumps")["pumps"]
        list_s = time.time() - t1
        # The web UI's fleet view reads every pump's view in one request.
        fleet_s = []
        for _ in range(5):
            t2 = time.time()
            fleet = srv.call("GET", "/api/v1/fleet")["pumps"]
            fleet_s.append(time.time() - t2)
        time.sleep(1.0)
        after = rss_mb(srv.proc.pid)
        print(f"pumps registered: {len(pumps)}; PUT model: {n / dt:.0f}/s; GET /pumps: {1000 * list_s:.0f} ms")
        print(f"GET /fleet ({len(fleet)} pump views): {1000 * min(fleet_s):.0f} ms best of 5, "
              f"{1000 * sorted(fleet_s)[2]:.0f} ms median")
        print(f"server RSS: {before:.1f} MB before, {after:.1f} MB with {n} pumps registered")
    finally:
        srv.stop()


if __name__ == "__main__":
    main()
