#!/usr/bin/env python3
"""The demo's REST client (python3 standard library only): registers pumps'
models, sets each pump's proposed reference, waits until every run is
analysed and prints what the server concluded, per pump and run.

  service_client.py URL TOKEN register PLANT.json PUMP [PUMP ...]
  service_client.py URL TOKEN conclude PUMP [PUMP ...]
"""
import json
import sys
import time
import urllib.error
import urllib.parse
import urllib.request


def call(url, token, method, path, body=None):
    data = None if body is None else body.encode()
    req = urllib.request.Request(url + path, data=data, method=method,
                                 headers={"Authorization": "Bearer " + token, "Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read() or b"null")
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")


def seg(s):
    return urllib.parse.quote(s, safe="")


def register(url, token, plant_path, pumps):
    plant = open(plant_path).read()
    for p in pumps:
        status, j = call(url, token, "PUT", f"/api/v1/pumps/{seg(p)}/model", plant)
        if status != 200:
            sys.exit(f"PUT model of {p}: {status} {j}")
        print(f"{p}: model version {j['model_version']} registered")


def wait_all(url, token, run_ids, reference_version, timeout_s=900):
    deadline = time.time() + timeout_s
    pending = set(run_ids)
    results = {}
    while pending and time.time() < deadline:
        for r in sorted(pending):
            status, a = call(url, token, "GET", f"/api/v1/runs/{seg(r)}/analysis")
            if status == 200 and a["status"] in ("done", "failed") and a.get("reference_version", 0) >= reference_version:
                results[r] = a
        pending -= set(results)
        if pending:
            time.sleep(1)
    if pending:
        sys.exit(f"not analysed in {timeout_s} s: {sorted(pending)}")
    return results


def conclude(url, token, pumps):
    failed = 0
    for p in pumps:
        status, pump = call(url, token, "GET", f"/api/v1/pumps/{seg(p)}")
        ref = pump.get("reference")
        if not ref or ref["status"] != "proposed":
            sys.exit(f"{p}: no proposed reference: {pump}")
        status, j = call(url, token, "PUT", f"/api/v1/pumps/{seg(p)}/reference", json.dumps({"runs": ref["runs"]}))
        if status != 202:
            sys.exit(f"PUT reference of {p}: {status} {j}")
        print(f"{p}: reference version {j['reference_version']} = its first {len(ref['runs'])} runs (job {j['job_id']})")
    print()
    print(f"{'pump':8} {'run':42} {'rpm':>7} {'status':7} {'modes':>5} {'nrmse':>6} {'T/thr':>7}  conclusion")
    for p in pumps:
        _, runs = call(url, token, "GET", f"/api/v1/pumps/{seg(p)}/runs")
        ids = [r["run_id"] for r in runs["runs"] if r["kind"] == "identification" and r["status"] == "complete"]
        results = wait_all(url, token, ids, 1)
        for r in ids:
            a = results[r]
            if a["status"] != "done":
                failed += 1
                print(f"{p:8} {r:42} {'':>7} failed  {a.get('error', '')}")
                continue
            d = a.get("detection") or {}
            conclusion = "no change"
            if d.get("detected"):
                f = (a.get("diagnosis") or {}).get("faults") or [{"fault": "unknown", "parameters": {}}]
                params = ", ".join(f"{k} {v:.3g}" for k, v in f[0]["parameters"].items() if isinstance(v, (int, float)))
                conclusion = f"CHANGE: {f[0]['fault']} ({params})"
            print(f"{p:8} {r:42} {a['speed_rpm']:7.0f} {a['status']:7} {len(a.get('modes', [])):5d} "
                  f"{a.get('nrmse', 0):6.3f} {d.get('ratio', 0):7.3f}  {conclusion}")
        _, pump = call(url, token, "GET", f"/api/v1/pumps/{seg(p)}")
        print(f"{p:8} health: {pump['health']}")
    return failed


if __name__ == "__main__":
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    url, token, cmd = sys.argv[1], sys.argv[2], sys.argv[3]
    if cmd == "register":
        register(url, token, sys.argv[4], sys.argv[5:])
    elif cmd == "conclude":
        sys.exit(1 if conclude(url, token, sys.argv[4:]) else 0)
    else:
        sys.exit(__doc__)
