"""A throwaway `ambdiag serve` for the service benchmarks: a fresh historian
in a temporary folder, an engineer token, the server on a free port over the
loopback Cyclone DDS configuration, and a JSON REST call with the token."""
import json
import os
import re
import subprocess
import tempfile
import time
import urllib.request

CYCLONE_URI = "file://" + os.path.abspath(os.path.join(os.path.dirname(__file__), "../../deploy/cyclonedds/local.xml"))


class BenchServer:
    def __init__(self, build, prefix, domain, partition, extra=()):
        self.cli = os.path.join(build, "cli", "ambdiag")
        self.tmp = tempfile.mkdtemp(prefix=prefix)
        self.domain, self.partition = domain, partition
        self.env = dict(os.environ, CYCLONEDDS_URI=CYCLONE_URI)
        db = os.path.join(self.tmp, "h.db")
        out = subprocess.check_output([self.cli, "token", "add", "--db", db, "--role", "engineer", "--name", "b", "--json"])
        self.token = json.loads(out)["token"]
        log = open(os.path.join(self.tmp, "server.log"), "w+")
        # Capacity is measured, not the per-token limit, unless asked for.
        limit = [] if "--rate-limit" in extra else ["--rate-limit", "0"]
        self.proc = subprocess.Popen([self.cli, "serve", "--db", db, "--http-port", "0", "--domain", domain,
                                      "--partition", partition, *limit, *extra], stderr=log, env=self.env)
        self.port = None
        for _ in range(100):
            log.seek(0)
            m = re.search(r"REST on port (\d+)", log.read())
            if m:
                self.port = int(m.group(1))
                break
            time.sleep(0.1)
        if self.port is None:
            self.stop()
            raise RuntimeError(f"the server did not start; see {log.name}")
        self.url = f"http://127.0.0.1:{self.port}"

    def call(self, method, path, body=None):
        """The JSON answer of METHOD PATH (body: str or bytes) with the token."""
        data = body.encode() if isinstance(body, str) else body
        req = urllib.request.Request(self.url + path, data=data, method=method,
                                     headers={"Authorization": "Bearer " + self.token, "Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=60) as r:
            return json.loads(r.read())

    def stop(self):
        self.proc.terminate()
        self.proc.wait()
