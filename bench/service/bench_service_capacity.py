#!/usr/bin/env python3
"""What one `ambdiag serve` analyses per CPU-second, ingest included (issue 16).

  bench_service_capacity.py BUILD_DIR DATA_DIR [PUMPS] [RUNS_PER_PUMP]

Starts a server (2 workers) on a fresh historian, registers PUMPS pumps
(default 4) with the reference pump's model, streams two healthy runs per
pump (copies of reference_pump/run_ref_1 under new ids) and sets them as the
pump's reference; then, measured, streams RUNS_PER_PUMP more runs per pump
(default 4; alternately the healthy run and the dry-run fault run, so half
are diagnosed) with real agents (`ambdiag-agent replay --fast`) and waits
until every run is analysed. Prints the server's CPU (user + system, all
threads: ingest, analysis, REST) per analysed run, the jobs' own CPU
(healthy / with diagnosis), the latency from a run's end to its analysis,
and the pumps one 2-core server could analyse at one run an hour. Then
the ingest check: 8 runs of pumps without a model streamed alone, and again
while the workers chew a backlog (every run above re-queued by a new model
version): the ingest rate with and without the backlog."""
import json
import os
import statistics
import subprocess
import sys
import time
import urllib.parse

from bench_server import BenchServer

TICK = os.sysconf("SC_CLK_TCK")


def cpu_s(pid):
    f = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(f[11]) + int(f[12])) / TICK


def main():
    build, data = sys.argv[1], sys.argv[2]
    n_pumps = int(sys.argv[3]) if len(sys.argv) > 3 else 4
    n_runs = int(sys.argv[4]) if len(sys.argv) > 4 else 4
    agent = os.path.join(build, "edge_agent", "ambdiag-agent")
    srv = BenchServer(build, "bench_capacity_", "43", "capacity", ["--workers", "2"])
    tmp, env, domain, part, call = srv.tmp, srv.env, srv.domain, srv.partition, srv.call

    def copy(src, pump, run_id):
        d = os.path.join(tmp, "runs", run_id.replace("/", "_"))
        os.makedirs(d, exist_ok=True)
        meta = json.load(open(os.path.join(src, "run.json")))
        meta.update(pump_id=pump, run_id=run_id)
        json.dump(meta, open(os.path.join(d, "run.json"), "w"))
        if not os.path.exists(os.path.join(d, "samples.f32")):
            os.symlink(os.path.abspath(os.path.join(src, "samples.f32")), os.path.join(d, "samples.f32"))
        return d

    def stream(dirs):
        procs = []
        for i, d in enumerate(dirs):
            procs.append(subprocess.Popen([agent, "replay", d, "--fast", "--domain", domain, "--partition", part,
                                           "--spool-dir", os.path.join(tmp, f"spool_{i % 4}_{len(procs)}")],
                                          stderr=subprocess.DEVNULL, env=env))
            if len(procs) % 4 == 0:
                for p in procs[-4:]:
                    p.wait()
        for p in procs:
            p.wait()

    def wait_done(run_ids, ref_version):
        while True:
            left = 0
            for r in run_ids:
                a = call("GET", f"/api/v1/runs/{urllib.parse.quote(r, safe='')}/analysis")
                if not (a["status"] in ("done", "failed") and a.get("reference_version", 0) >= ref_version):
                    left += 1
            if left == 0:
                return
            time.sleep(0.5)

    healthy, dry = os.path.join(data, "reference_pump/run_ref_1"), os.path.join(data, "fault_dry_run/run")
    plant = open(os.path.join(data, "reference_pump/plant.json")).read()
    pumps = [f"C-{i:03d}" for i in range(n_pumps)]
    try:
        for p in pumps:
            call("PUT", f"/api/v1/pumps/{p}/model", plant)
        refs = {p: [f"{p}/ref-{k}" for k in range(2)] for p in pumps}
        stream([copy(healthy, p, r) for p in pumps for r in refs[p]])
        for p in pumps:
            call("PUT", f"/api/v1/pumps/{p}/reference", json.dumps({"runs": refs[p]}))
        wait_done([r for p in pumps for r in refs[p]], 1)

        runs = [(p, f"{p}/run-{k}", dry if k % 2 else healthy) for k in range(n_runs) for p in pumps]
        cpu0, t0 = cpu_s(srv.proc.pid), time.time()
        stream([copy(src, p, r) for p, r, src in runs])
        wait_done([r for _, r, _ in runs], 1)
        wall, cpu = time.time() - t0, cpu_s(srv.proc.pid) - cpu0
        jobs = [call("GET", f"/api/v1/jobs?run_id={urllib.parse.quote(r, safe='')}&status=done&kind=analysis")["jobs"] for _, r, _ in runs]
        detail = [call("GET", f"/api/v1/jobs/{j[0]['job_id']}") for j in jobs]
        h = [d["result"]["cpu_s"] for d in detail if not d["result"]["detection"]["detected"]]
        f = [d["result"]["cpu_s"] for d in detail if d["result"]["detection"]["detected"]]
        info = [call("GET", f"/api/v1/runs/{urllib.parse.quote(r, safe='')}") for _, r, _ in runs]

        def ts(s):
            return time.mktime(time.strptime(s[:19], "%Y-%m-%dT%H:%M:%S")) + float("0." + s[20:23])
        lat = [ts(d["finished_at"]) - ts(i["ended_at"]) for d, i in zip(detail, info)]
        per_run = cpu / len(runs)
        print(f"{len(runs)} runs of {len(pumps)} pumps streamed and analysed in {wall:.1f} s wall")
        print(f"server CPU (ingest + analysis + REST): {cpu:.1f} s, {per_run:.2f} s per run")
        print(f"job CPU: healthy {statistics.mean(h):.2f} s (n {len(h)}, {min(h):.2f}-{max(h):.2f}), "
              f"with diagnosis {statistics.mean(f) if f else 0:.2f} s (n {len(f)})")
        print(f"run end -> analysis done: median {statistics.median(lat):.1f} s, max {max(lat):.1f} s (queue included)")
        print(f"pumps at one run an hour on 2 cores: {2 * 3600 / per_run:.0f} (this mix), "
              f"{2 * 3600 / (per_run - statistics.mean(f) / 2 + statistics.mean(h) / 2) if f else 0:.0f} (all healthy)")

        # Ingest first: streaming rate alone and beside an analysis backlog.
        def ingest_rate(tag):
            dirs = [copy(healthy, f"I-{tag}-{k}", f"I-{tag}-{k}/run") for k in range(8)]
            t = time.time()
            stream(dirs)
            return 8 * os.path.getsize(os.path.join(healthy, "samples.f32")) / 1e6 / (time.time() - t)
        alone = ingest_rate("a")
        for p in pumps:
            call("PUT", f"/api/v1/pumps/{p}/model", plant)  # version 2: every run queued again
        time.sleep(0.5)
        queued = len(call("GET", "/api/v1/jobs?status=queued")["jobs"]) + len(call("GET", "/api/v1/jobs?status=running")["jobs"])
        beside = ingest_rate("b")
        left = len(call("GET", "/api/v1/jobs?status=queued")["jobs"])
        print(f"ingest (8 runs, 4 agents at a time): {alone:.0f} MB/s alone, {beside:.0f} MB/s beside a backlog of "
              f"{queued} analysis jobs ({left} still queued after the streaming)")
    finally:
        srv.stop()


if __name__ == "__main__":
    main()
