#!/usr/bin/env python3
"""failover.py - sdfd replicas behind HAProxy or nginx lose no request when one dies.

Starts N replicas of the built sdfd on loopback (each serving the same mesh directory), a
reference sdfd, and the load balancer from deploy/lb/ (its own file, with only the addresses
and the routing mode changed), then runs deploy/loadgen.py's load through the balancer. Mid-run
one replica is SIGKILLed and started again, and later another is SIGTERMed (it drains and
exits). It passes when:
  - no request failed and every answer is byte-equal to the reference's;
  - the load ran across both events, the SIGTERMed replica exited 0 and logged its drain;
  - a query on the binary port through the balancer answers the same bits as the reference;
  - with --mode hash: before the kill each mesh was served by exactly one replica, and every
    query of a mesh was served by that replica whenever it was up (outside the time from its
    kill to a few seconds after it was ready again, and after its SIGTERM) -- read from the
    replicas' own request logs, whose point counts name the mesh (loadgen.py).

    python3 deploy/failover.py --sdfd build/server/sdfd --lb haproxy --mode hash

Needs haproxy or nginx (with the stream module) from Debian, and numpy. Every process it
starts listens on 127.0.0.1 only and is stopped before it exits.
"""
import argparse
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
import loadgen  # noqa: E402
import sdfclient  # noqa: E402

MESH_FILES = ("cow.off", "knot1.off", "fandisk.off", "elephant-with-holes.off", "spider.obj",
              "bear.off")
RECOVERY_SECONDS = 4.0  # a restarted replica is back in rotation by then (checks, fail_timeout)


def free_ports(n):
    socks = [socket.socket() for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def get(url, timeout=2):
    try:
        with urllib.request.urlopen(url, timeout=timeout) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code
    except OSError:
        return None


def wait_for(what, test, seconds=30):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if test():
            return
        time.sleep(0.05)
    raise RuntimeError(f"timed out waiting for {what}")


class Sdfd:
    """One sdfd process on loopback; each start writes a new log (name.N.log)."""

    def __init__(self, binary, name, mesh_dir, tmp):
        self.binary, self.name, self.mesh_dir, self.tmp = binary, name, mesh_dir, tmp
        self.http_port, self.bin_port = free_ports(2)
        self.proc, self.logs = None, []

    @property
    def url(self):
        return f"http://127.0.0.1:{self.http_port}"

    def start(self):
        log = os.path.join(self.tmp, f"{self.name}.{len(self.logs)}.log")
        self.logs.append(log)
        with open(log, "wb") as f:
            self.proc = subprocess.Popen(
                [self.binary, "--http", f"127.0.0.1:{self.http_port}",
                 "--bin", f"127.0.0.1:{self.bin_port}", "--mesh-dir", self.mesh_dir,
                 "--threads", "1", "--drain-seconds", "10"],
                stdout=subprocess.DEVNULL, stderr=f)
        wait_for(f"{self.name} ready", lambda: get(self.url + "/readyz") == 200)
        return time.time()

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    def served(self):
        """(ts, points) of every query answered 200, over all of this replica's logs."""
        out = []
        for log in self.logs:
            for line in open(log, errors="replace"):
                try:
                    e = json.loads(line)
                except ValueError:
                    continue
                if (e.get("event") == "request" and e.get("status") == 200
                        and e.get("route") == "/v1/meshes/{name}/query"):
                    out.append((e["ts"], e["points"]))
        return out


def start_haproxy(tmp, mode, replicas, http_port, bin_port):
    env = dict(os.environ, SDFD_ROUTING=mode, LB_HTTP=f"127.0.0.1:{http_port}",
               LB_BIN=f"127.0.0.1:{bin_port}")
    for i, r in enumerate(replicas, 1):
        env[f"SDFD_{i}_HTTP"] = f"127.0.0.1:{r.http_port}"
        env[f"SDFD_{i}_BIN"] = f"127.0.0.1:{r.bin_port}"
        env[f"SDFD_{i}_HTTP_PORT"] = str(r.http_port)
    cfg = os.path.join(HERE, "lb", "haproxy.cfg")
    subprocess.run(["haproxy", "-c", "-q", "-f", cfg], env=env, check=True)
    log = open(os.path.join(tmp, "haproxy.log"), "wb")
    return subprocess.Popen(["haproxy", "-db", "-f", cfg], env=env, stdout=log, stderr=log)


def replace_once(text, old, new, count=1):
    if text.count(old) != count:
        raise RuntimeError(f"nginx.conf: expected {count} of {old!r}, found {text.count(old)}")
    return text.replace(old, new)


def start_nginx(tmp, mode, replicas, http_port, bin_port):
    """deploy/lb/nginx.conf with only its addresses and routing mode changed."""
    text = open(os.path.join(HERE, "lb", "nginx.conf")).read()
    text = replace_once(text, "set $sdfd_pool sdfd_leastconn;", f"set $sdfd_pool sdfd_{mode};")
    text = replace_once(text, "listen 0.0.0.0:8080;", f"listen 127.0.0.1:{http_port};")
    text = replace_once(text, "listen 0.0.0.0:9090;", f"listen 127.0.0.1:{bin_port};")
    opts = " max_fails=1 fail_timeout=2s;"
    defaults = [(8081, 9091), (8082, 9092)]
    for (h, b), r in zip(defaults, replicas):
        text = replace_once(text, f"server 127.0.0.1:{h}{opts}",
                            f"server 127.0.0.1:{r.http_port}{opts}", 2)
        text = replace_once(text, f"server 127.0.0.1:{b}{opts}",
                            f"server 127.0.0.1:{r.bin_port}{opts}")
    for r in replicas[len(defaults):]:  # more replicas: a server line after the last one
        last = replicas[len(defaults) - 1]
        text = text.replace(f"server 127.0.0.1:{last.http_port}{opts}",
                            f"server 127.0.0.1:{last.http_port}{opts}\n"
                            f"        server 127.0.0.1:{r.http_port}{opts}")
        text = text.replace(f"server 127.0.0.1:{last.bin_port}{opts}",
                            f"server 127.0.0.1:{last.bin_port}{opts}\n"
                            f"        server 127.0.0.1:{r.bin_port}{opts}")
    conf = os.path.join(tmp, "nginx.conf")
    with open(conf, "w") as f:
        f.write(text)
    glob = f"pid {tmp}/nginx.pid;"
    subprocess.run(["nginx", "-q", "-t", "-p", tmp, "-c", conf, "-g", glob], check=True)
    log = open(os.path.join(tmp, "nginx.log"), "wb")
    return subprocess.Popen(["nginx", "-p", tmp, "-c", conf, "-g", glob], stdout=log, stderr=log)


def check_binary(bin_port, ref, mesh):
    """One binary-protocol query through the balancer, compared bit for bit."""
    pts = np.random.default_rng(7).uniform(-1.5, 1.5, (5000, 3)).astype(np.float32)
    answers = []
    for port in (bin_port, ref.bin_port):
        c = sdfclient.BinaryClient("127.0.0.1", port)
        answers.append(c.query(mesh, pts, mode="gradient"))
        c.close()
    got, want = answers
    return all(np.asarray(got[k]).tobytes() == np.asarray(want[k]).tobytes() for k in want)


def lb_retries(tmp, lb):
    """Requests the balancer sent to more than one replica, from its access log."""
    n = 0
    for line in open(os.path.join(tmp, lb + ".log"), errors="replace"):
        if lb == "haproxy" and re.search(r" \d+/\d+/\d+/\d+/\+\d+ ", line):
            n += 1
        if lb == "nginx" and re.search(r"upstream=[^ ]+, ", line):
            n += 1
    return n


def owners(replicas, n_meshes, until):
    """mesh index -> set of replica indexes that answered its queries before `until`."""
    seen = {m: set() for m in range(n_meshes)}
    for i, r in enumerate(replicas):
        for ts, points in r.served():
            if ts < until:
                seen[points % n_meshes].add(i)
    return seen


def check_hash(replicas, n_meshes, t_kill, windows):
    """The hashing checks; returns a list of problems (empty when it holds)."""
    problems = []
    before = owners(replicas, n_meshes, t_kill)
    owner = {}
    for m, s in before.items():
        if len(s) != 1:
            problems.append(f"mesh {m}: served by replicas {sorted(s)} before the kill")
        else:
            owner[m] = next(iter(s))
    for i, r in enumerate(replicas):
        for ts, points in r.served():
            m = points % n_meshes
            o = owner.get(m)
            if o is None or o == i:
                continue
            if not any(a <= ts <= b for a, b in windows[o]):
                problems.append(f"mesh {m} (owner {o}) served by replica {i} at {ts:.3f}, "
                                f"while {o} was up")
    return problems, owner


def choose_targets(replicas, n_meshes, mode):
    """(kill, term): in hash mode two replicas that each own a mesh."""
    if mode != "hash":
        return 0, 1
    counts = {}
    for m, s in owners(replicas, n_meshes, float("inf")).items():
        for i in s:
            counts[i] = counts.get(i, 0) + 1
    owning = sorted(counts, key=lambda i: -counts[i])
    if len(owning) < 2:
        raise RuntimeError(f"hashing put every mesh on one replica ({counts}); use more meshes")
    return owning[0], owning[1]


def scenario(a, tmp):
    mesh_dir = os.path.join(tmp, "meshes")
    os.mkdir(mesh_dir)
    for f in MESH_FILES:
        shutil.copy(os.path.join(ROOT, "tests", "data", f), mesh_dir)
    meshes = [os.path.splitext(f)[0] for f in MESH_FILES]
    n = len(meshes)
    ref = Sdfd(a.sdfd, "reference", mesh_dir, tmp)
    replicas = [Sdfd(a.sdfd, f"replica{i}", mesh_dir, tmp) for i in range(a.replicas)]
    procs = [ref] + replicas
    lb = None
    try:
        for p in procs:
            p.start()
        http_port, bin_port = free_ports(2)
        start = start_haproxy if a.lb == "haproxy" else start_nginx
        lb = start(tmp, a.mode, replicas, http_port, bin_port)
        lb_url = f"http://127.0.0.1:{http_port}"
        wait_for("the balancer", lambda: get(lb_url + "/v1/meshes") == 200)
        binary_ok = check_binary(bin_port, ref, meshes[0])
        reqs = loadgen.make_requests(meshes, a.requests)
        loadgen.fetch_expected(ref.url, reqs)

        result = {}
        load = threading.Thread(target=lambda: result.setdefault(
            "stats", loadgen.run(lb_url, reqs, a.workers, a.seconds, a.max_requests)))
        t0 = time.time()
        load.start()
        time.sleep(a.seconds * 0.2)
        kill, term = choose_targets(replicas, n, a.mode)
        t_kill = time.time()
        replicas[kill].proc.send_signal(signal.SIGKILL)
        replicas[kill].proc.wait()
        time.sleep(0.5)
        t_ready = replicas[kill].start()
        time.sleep(max(0.0, t0 + a.seconds * 0.55 - time.time()))
        t_term = time.time()
        replicas[term].proc.send_signal(signal.SIGTERM)
        term_rc = replicas[term].proc.wait(timeout=30)
        t_exit = time.time()
        load.join()
        t_end = time.time()
        stats = result["stats"]
    finally:
        if lb:
            lb.terminate()
            lb.wait(timeout=10)
        for p in procs:
            p.stop()

    drain_log = open(replicas[term].logs[-1]).read()
    retried = lb_retries(tmp, a.lb)
    windows = {i: [] for i in range(len(replicas))}
    windows[kill].append((t_kill, t_ready + RECOVERY_SECONDS))
    windows[term].append((t_term, float("inf")))
    done = stats.done_at
    report = {
        "lb": a.lb, "mode": a.mode, "replicas": a.replicas,
        **{k: v for k, v in stats.summary().items()},
        "ok_after_kill": sum(t > t_kill for t in done),
        "ok_after_term": sum(t > t_term for t in done),
        "killed": kill, "restart_ready_s": round(t_ready - t_kill, 3),
        "terminated": term, "term_exit": term_rc, "drain_s": round(t_exit - t_term, 3),
        "binary_equal": binary_ok, "lb_retried": retried, "seconds": round(t_end - t0, 1),
    }
    problems = []
    if stats.failed or stats.mismatched:
        problems.append(f"{stats.failed} failed, {stats.mismatched} mismatched requests")
    if stats.ok < 100 or report["ok_after_kill"] == 0 or report["ok_after_term"] == 0:
        problems.append("the load did not run across both events")
    if t_end < t_exit:
        problems.append("the load ended before the drain")
    if term_rc != 0 or "SIGTERM: draining" not in drain_log or '"stopped"' not in drain_log:
        problems.append(f"the SIGTERMed replica exited {term_rc} or did not log its drain")
    if not binary_ok:
        problems.append("a binary query through the balancer differed from the reference")
    if a.mode == "hash":
        hp, owner = check_hash(replicas, n, t_kill, windows)
        problems += hp
        report["owner"] = {meshes[m]: o for m, o in owner.items()}
    served = [len(r.served()) for r in replicas]
    report["served_per_replica"] = served
    if min(served) == 0:
        problems.append(f"a replica served nothing: {served}")
    report["problems"] = problems
    return report


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sdfd", default=os.path.join(ROOT, "build", "server", "sdfd"))
    ap.add_argument("--lb", choices=("haproxy", "nginx"), required=True)
    ap.add_argument("--mode", choices=("leastconn", "hash"), required=True)
    ap.add_argument("--replicas", type=int, default=3, choices=(2, 3))
    ap.add_argument("--seconds", type=float, default=12)
    ap.add_argument("--workers", type=int, default=6)
    ap.add_argument("--requests", type=int, default=48)
    ap.add_argument("--max-requests", type=int, default=20000)
    ap.add_argument("--keep", action="store_true", help="keep the logs' folder")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="sdfd-failover-")
    try:
        report = scenario(a, tmp)
    finally:
        if not a.keep:
            shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(report))
    if a.keep:
        print(f"logs: {tmp}")
    if report["problems"]:
        print("FAIL: " + "; ".join(report["problems"]))
        return 1
    print(f"ok: {a.lb} {a.mode}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
