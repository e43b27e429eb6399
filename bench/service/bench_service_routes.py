#!/usr/bin/env python3
"""The service's own routes (issue 19 benchmark).

  bench_service_routes.py BUILD_DIR PLANT.json [N]

Starts a server on a fresh historian and measures, over loopback with one
keep-alive connection: GET /metrics (N scrapes: median and p95), GET
/api/v1/pumps (N requests/s, every one counted in the metrics and passed
through the rate limiter's bookkeeping with --rate-limit 1e6), and the
delay from sending a PUT model to reading its model.new event on an open
GET /api/v1/events stream (N/10 PUTs: median and max). Then, with a second
server at --rate-limit 50 (bursts of 100), how many of 400 back-to-back
requests of one token are answered 200 and 429. Figures go to
docs/benchmarks.md."""
import http.client
import json
import statistics
import sys
import threading
import time

from bench_server import BenchServer


def timed(conn, method, path, headers, body=None):
    t0 = time.perf_counter()
    conn.request(method, path, body=body, headers=headers)
    r = conn.getresponse()
    r.read()
    return r.status, time.perf_counter() - t0


def events_reader(port, token, seen, ready):
    """Collects (arrival time, model_version) of model.new events."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    conn.request("GET", "/api/v1/events?access_token=" + token)
    r = conn.getresponse()
    ready.set()
    buf = b""
    while True:
        chunk = r.read1(65536)
        if not chunk:
            return
        buf += chunk
        while b"\n\n" in buf:
            frame, buf = buf.split(b"\n\n", 1)
            lines = dict(l.split(": ", 1) for l in frame.decode().split("\n") if ": " in l and not l.startswith(":"))
            if lines.get("event") == "model.new":
                seen[json.loads(lines["data"])["model_version"]] = time.perf_counter()


def main():
    build, plant_path = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 1000
    plant = open(plant_path, "rb").read()
    srv = BenchServer(build, "bench_routes_", "43", "bench", ["--quiet"])
    try:
        auth = {"Authorization": "Bearer " + srv.token}
        conn = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=60)
        for i in range(20):
            timed(conn, "GET", "/api/v1/pumps", auth)  # warm-up
        scrapes = sorted(timed(conn, "GET", "/metrics", {})[1] for _ in range(n))
        t0 = time.perf_counter()
        for _ in range(n):
            timed(conn, "GET", "/api/v1/pumps", auth)
        pumps_rate = n / (time.perf_counter() - t0)
        seen, ready = {}, threading.Event()
        threading.Thread(target=events_reader, args=(srv.port, srv.token, seen, ready), daemon=True).start()
        ready.wait(10)
        delays = []
        for _ in range(max(1, n // 10)):
            sent = time.perf_counter()
            conn.request("PUT", "/api/v1/pumps/B-1/model", body=plant, headers=auth)
            r = conn.getresponse()
            version = json.loads(r.read())["model_version"]
            while version not in seen and time.perf_counter() - sent < 5:
                time.sleep(0.0002)
            delays.append(seen.get(version, float("inf")) - sent)
        delays.sort()
        print(f"GET /metrics: median {1000 * statistics.median(scrapes):.2f} ms, p95 {1000 * scrapes[int(0.95 * n)]:.2f} ms "
              f"({n} scrapes)")
        print(f"GET /api/v1/pumps: {pumps_rate:.0f} requests/s (one keep-alive connection)")
        print(f"PUT model sent -> its model.new read from the stream: median {1000 * statistics.median(delays):.2f} ms, "
              f"max {1000 * delays[-1]:.2f} ms ({len(delays)} PUTs)")
    finally:
        srv.stop()
    limited = BenchServer(build, "bench_routes_", "44", "bench", ["--quiet", "--rate-limit", "50"])
    try:
        conn = http.client.HTTPConnection("127.0.0.1", limited.port, timeout=60)
        auth = {"Authorization": "Bearer " + limited.token}
        t0 = time.perf_counter()
        codes = [timed(conn, "GET", "/api/v1/pumps", auth)[0] for _ in range(400)]
        dt = time.perf_counter() - t0
        print(f"--rate-limit 50 (bursts of 100): 400 requests in {dt:.2f} s: {codes.count(200)} answered 200, "
              f"{codes.count(429)} 429 (expected about {100 + 50 * dt:.0f} 200)")
    finally:
        limited.stop()


if __name__ == "__main__":
    main()
