#!/usr/bin/env python3
"""failover.py - sdfd replicas sharing one PostgreSQL catalog behind HAProxy or nginx lose no
request and no acknowledged write when one dies.

Starts a PostgreSQL of its own (tests/server/pgserver.py: Debian's postgresql, initdb into a
temporary directory), N replicas of the built sdfd on loopback sharing it (--catalog, with a
--max-resident-bytes below what they are given, so that items leave memory and come back from
the catalog), a reference sdfd that loads the same mesh files itself (no catalog), and the load
balancer from deploy/lb/ (its own file, with only the addresses and the routing mode changed).
Through the balancer it uploads the meshes (PUT) and bakes a volume, and checks with
deploy/shared_store.py that every replica answers them bit-equal to the reference and sees a
replacement and a deletion within the staleness window. Then it runs deploy/loadgen.py's load
of the meshes and the volume through the balancer, over HTTP and, at the same time, over the
binary protocol on the balancer's TCP port: workers of each client, one connection each for
the whole run -- Python (sdfclient.BinaryClient threads), JavaScript (node
clients/js/test/loadworker.js, a BinaryClient) and C (sdfc-load, built from
tests/clients/sdfc_load.c with libsdfclient, opts.resend) -- each of which sends a query once
more on a new connection when its connection dies or a draining replica refuses it, and
compares every answer bit for bit with the reference's. Mid-run one replica is SIGKILLed and started again, and later another is
SIGTERMed (it drains and exits), while a writer PUTs and DELETEs other names through the
balancer. It passes when:
  - the shared-store checks pass;
  - afterwards every replica serves the writer's last acknowledged write of each name (or a
    later one whose answer the kill lost), all of them the same;
  - no request failed and every answer is byte-equal to the reference's, over HTTP and over
    the binary protocol from every client (0 lost binary answers; the report counts sent,
    answered, lost and mismatched per language);
  - each binary worker whose connection was on the killed or the SIGTERMed replica (the
    replica that answered its last query before the event, from the replicas' logs) opened a
    new connection for each such event, and each event hit at least one worker;
  - the load ran across both events, the SIGTERMed replica exited 0 and logged its drain;
  - every name the killed replica served before its kill was served by another replica after;
  - a query on the binary port through the balancer answers the same bits as the reference;
  - with --mode leastconn: the replicas evicted items (each sees every name, and the budget is
    under their sum);
  - with --mode hash: during the load before the kill each name was served by exactly one
    replica, which loaded at most each of its names (and the binary load's one) once (its
    share fits the budget), and every query of a name was served by that replica whenever it
    was up (outside the time from its kill to a few seconds after it was ready again, and
    after its SIGTERM) -- read from the replicas' own request logs, whose point counts name
    the mesh or volume (loadgen.py).

    python3 deploy/failover.py --sdfd build/server/sdfd --lb haproxy --mode hash

Needs haproxy or nginx (with the stream module) from Debian, numpy, node 18+ and the build's
sdfc-load (--js-workers 0 / --c-workers 0 leave those out). Every process it
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
sys.path.insert(0, os.path.join(ROOT, "tests", "server"))
import loadgen  # noqa: E402
import pgserver  # noqa: E402
import sdfclient  # noqa: E402
import shared_store  # noqa: E402

MESH_FILES = ("cow.off", "knot1.off", "fandisk.off", "elephant-with-holes.off", "spider.obj",
              "bear.off")
RECOVERY_SECONDS = 4.0  # a restarted replica is back in rotation by then (checks, fail_timeout)
TOKEN = "failover-token"
WRITTEN = ("written0", "written1", "written2")  # the writer's names
BAKED = ("fandisk", "fandisk-sdf", 40)  # mesh, volume, resolution
QUERY_ROUTES = ("/v1/meshes/{name}/query", "/v1/volumes/{name}/query")
BINARY_QUERIES = ("QUERY", "VOLUME_QUERY")


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

    def __init__(self, binary, name, args, tmp):
        self.binary, self.name, self.args, self.tmp = binary, name, args, tmp
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
                 "--bin", f"127.0.0.1:{self.bin_port}", "--token", TOKEN,
                 "--threads", "1", "--drain-seconds", "10", *self.args],
                stdout=subprocess.DEVNULL, stderr=f)
        wait_for(f"{self.name} ready", lambda: get(self.url + "/readyz") == 200)
        return time.time()

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    def requests(self, since, wanted):
        """(ts, points) of every request log event from `since` on, over all of this
        replica's logs, that `wanted(event)` accepts."""
        out = []
        for log in self.logs:
            for line in open(log, errors="replace"):
                try:
                    e = json.loads(line)
                except ValueError:
                    continue
                if e.get("event") == "request" and e["ts"] >= since and wanted(e):
                    out.append((e["ts"], e["points"]))
        return out

    def served(self, since):
        """Every HTTP query answered 200 from `since` on."""
        return self.requests(since, lambda e: e.get("status") == 200
                             and e.get("route") in QUERY_ROUTES)

    def served_binary(self, since):
        """Every binary QUERY and VOLUME_QUERY answered from `since` on."""
        return self.requests(since, lambda e: e.get("proto") == "binary"
                             and e.get("status") == 200 and e.get("method") in BINARY_QUERIES)

    def metric(self, name):
        """A counter or gauge from /metrics, as an int."""
        with urllib.request.urlopen(self.url + "/metrics", timeout=5) as r:
            for line in r.read().decode().splitlines():
                if line.split(" ")[0] == name:
                    return int(float(line.split(" ")[1]))
        raise RuntimeError(f"{self.name}: no {name} in /metrics")

    def peak_rss(self):
        """The process's peak resident memory (VmHWM), bytes."""
        for line in open(f"/proc/{self.proc.pid}/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
        return 0


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


def owners(replicas, n_names, since, until):
    """name index -> set of replica indexes that answered its queries in [since, until)."""
    seen = {m: set() for m in range(n_names)}
    for i, r in enumerate(replicas):
        for ts, points in r.served(since):
            if ts < until:
                seen[points % n_names].add(i)
    return seen


def check_hash(replicas, n_names, t0, t_kill, t_term, windows):
    """The hashing checks; returns a list of problems (empty when it holds) and the owners."""
    problems = []
    before = owners(replicas, n_names, t0, t_kill)
    owner = {}
    for m, s in before.items():
        if len(s) != 1:
            problems.append(f"name {m}: served by replicas {sorted(s)} before the kill")
        else:
            owner[m] = next(iter(s))
    for i, r in enumerate(replicas):
        for ts, points in r.served(t0):
            m = points % n_names
            o = owner.get(m)
            if o is None or o == i:
                continue
            if not any(a <= ts <= b for a, b in windows[o]):
                problems.append(f"name {m} (owner {o}) served by replica {i} at "
                                f"+{ts - t0:.3f} s (kill +{t_kill - t0:.3f}, term "
                                f"+{t_term - t0:.3f}), while {o} was up")
    return problems, owner


def check_survivors(replicas, n_names, t0, t_kill, kill):
    """Every name the killed replica served before its kill, another served after it."""
    before = owners(replicas, n_names, t0, t_kill)
    after = owners(replicas, n_names, t_kill, float("inf"))
    return [f"name {m}: no replica but the killed one served it after the kill"
            for m in range(n_names) if kill in before[m] and not after[m] - {kill}]


def choose_targets(replicas, n_names, mode, t0):
    """(kill, term): in hash mode two replicas that each own a name."""
    if mode != "hash":
        return 0, 1
    counts = {}
    for m, s in owners(replicas, n_names, t0, float("inf")).items():
        for i in s:
            counts[i] = counts.get(i, 0) + 1
    owning = sorted(counts, key=lambda i: -counts[i])
    if len(owning) < 2:
        raise RuntimeError(f"hashing put every name on one replica ({counts}); use more meshes")
    return owning[0], owning[1]


def prepare(a, tmp, ref):
    """The reference bakes the volume; the budget the replicas get: under the sum of what
    they will be given (every mesh and the volume), over it less any one item."""
    job, state = shared_store.bake(ref.url, BAKED[0], BAKED[1], BAKED[2], TOKEN)
    if state["state"] != "done":
        raise RuntimeError(f"the reference's bake: {state}")
    meshes = [os.path.splitext(f)[0] for f in MESH_FILES]
    sizes = shared_store.resident_bytes(ref.url, meshes, [BAKED[1]])
    budget = a.max_resident_bytes
    if budget < 0:
        budget = sum(sizes.values()) - min(sizes.values()) // 2
    return sizes, budget


def upload_and_check(a, lb_url, replicas, ref, mesh_dir):
    """Uploads and bakes through the balancer, then the shared-store checks; report, problems."""
    problems = []
    for f in MESH_FILES:
        status, body = shared_store.upload(lb_url, os.path.splitext(f)[0],
                                           os.path.join(mesh_dir, f), TOKEN)
        if status not in (200, 201):
            problems.append(f"PUT {f} through the balancer: {status} {body[:120]!r}")
    job, state = shared_store.bake(lb_url, BAKED[0], BAKED[1], BAKED[2], TOKEN)
    if state["state"] != "done":
        return {}, problems + [f"the bake through the balancer: {state}"]
    urls = [r.url for r in replicas]
    problems += shared_store.check_answers(lb_url, urls, ref.url, BAKED[0], BAKED[1], job,
                                           a.rounds)
    times, more = shared_store.check_staleness(
        lb_url, urls, ref.url, TOKEN, (os.path.join(mesh_dir, "cow.off"), "cow"),
        (os.path.join(mesh_dir, "knot1.off"), "knot1"))
    return times, problems + more


def store_counts(replicas):
    return [(r.metric("sdfd_store_loads_total"), r.metric("sdfd_store_evictions_total"))
            for r in replicas]


def worker_command(a, lang, bin_port, manifest, w):
    """The command of a JS or C binary worker (clients/js/test/loadworker.js, sdfc-load)."""
    tail = ["127.0.0.1", str(bin_port), manifest, str(a.seconds), str(100 + w)]
    if lang == "js":
        return [a.node, os.path.join(ROOT, "clients", "js", "test", "loadworker.js"), *tail]
    return [a.sdfc_load, *tail]


def finish_worker(proc, lang, seconds):
    """A JS or C worker's JSON counts; a failed worker's are one lost request and its
    output."""
    try:
        out, err = proc.communicate(timeout=seconds + 120)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
    lines = out.strip().splitlines()
    try:
        if proc.returncode == 0 and lines:
            return json.loads(lines[-1])
    except ValueError:
        pass
    return {"sent": 1, "ok": 0, "failed": 1, "mismatched": 0, "connects": 0, "resent": 0,
            "errors": [f"{lang} worker exited {proc.returncode}: {err[-300:]}"], "done_at": []}


def run_load(a, lb_url, bin_port, replicas, reqs, bin_reqs, n, external):
    """The HTTP and the binary load with their two events; a dict of what happened when.
    `external`: [(worker, language, manifest)], the JS and C binary workers."""
    ev = {"written": {}}
    stop_writer = threading.Event()
    writer = threading.Thread(target=shared_store.write_loop,
                              args=(lb_url, WRITTEN, TOKEN, stop_writer, ev["written"]))
    load = threading.Thread(target=lambda: ev.setdefault(
        "stats", loadgen.run(lb_url, reqs, a.workers, a.seconds, a.max_requests)))
    bin_load = threading.Thread(target=lambda: ev.setdefault(
        "binary", loadgen.run_binary(("127.0.0.1", bin_port), bin_reqs, a.seconds,
                                     a.max_requests)))
    ev["counts0"] = store_counts(replicas)
    ev["t0"] = time.time()
    load.start()
    bin_load.start()
    writer.start()
    procs = [(w, lang, subprocess.Popen(worker_command(a, lang, bin_port, m, w),
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        text=True, cwd=os.path.join(ROOT, "clients", "js")))
             for w, lang, m in external]
    time.sleep(a.seconds * 0.2)
    # The kill waits (up to 45 % of the run) until every name has been served: the checks
    # compare who served a name before and after it, which says nothing of an unserved name
    # (a slow machine can take longer than a fifth of the run to reach them all).
    while time.time() < ev["t0"] + a.seconds * 0.45 and \
            not all(owners(replicas, n, ev["t0"], time.time()).values()):
        time.sleep(0.1)
    ev["kill"], ev["term"] = kill, term = choose_targets(replicas, n, a.mode, ev["t0"])
    ev["counts1"] = store_counts(replicas)
    ev["t_kill"] = time.time()
    replicas[kill].proc.send_signal(signal.SIGKILL)
    replicas[kill].proc.wait()
    time.sleep(0.5)
    ev["t_ready"] = replicas[kill].start()
    time.sleep(max(0.0, ev["t0"] + a.seconds * 0.55 - time.time()))
    ev["t_term"] = time.time()
    replicas[term].proc.send_signal(signal.SIGTERM)
    ev["term_rc"] = replicas[term].proc.wait(timeout=30)
    ev["t_exit"] = time.time()
    load.join()
    bin_load.join()
    stop_writer.set()
    writer.join()
    ev["written_problems"] = shared_store.check_written(
        [r.url for r in replicas if r.proc.poll() is None], ev["written"])
    ev["external"] = {w: (lang, finish_worker(p, lang, a.seconds)) for w, lang, p in procs}
    ev["t_end"] = time.time()
    ev["rss"] = [r.peak_rss() if r.proc.poll() is None else None for r in replicas]
    return ev


def store_checks(a, replicas, ev, n, owner, budget):
    """The budget's checks; (loads, evictions) per replica from load start to kill, problems."""
    moved = [(l1 - l0, e1 - e0) for (l0, e0), (l1, e1) in zip(ev["counts0"], ev["counts1"])]
    problems = []
    if budget and a.mode == "leastconn" and not any(e for _, e in moved):
        problems.append(f"no replica evicted anything under a budget of {budget} B")
    if budget and a.mode == "hash":
        for i in range(len(replicas)):
            # the binary load's item reaches every replica (its port is not hashed)
            mine = sum(1 for o in owner.values() if o == i) \
                + sum(1 for m in ev["bin_items"] if owner.get(m) != i)
            if moved[i][0] > mine:
                problems.append(f"replica {i} loaded {moved[i][0]} items from the store during "
                                f"the load, more than the {mine} names it owns or the binary "
                                "load asks for")
    return moved, problems


def binary_items(a, names, sizes):
    """The indexes of the names the binary load queries. The binary port is balanced per
    connection, not hashed, so with hashing its queries reach every replica: there it asks
    for the smallest item only, which each replica can hold beside its own share of the
    budget (with every name, each would hold them all and evict without end)."""
    if a.mode != "hash":
        return list(range(len(names)))
    return [names.index(min(sizes, key=sizes.get))]


def scenario(a, tmp):
    mesh_dir = os.path.join(tmp, "meshes")
    os.mkdir(mesh_dir)
    for f in MESH_FILES:
        shutil.copy(os.path.join(ROOT, "tests", "data", f), mesh_dir)
    names = [os.path.splitext(f)[0] for f in MESH_FILES] + [BAKED[1]]
    n = len(names)
    ref = Sdfd(a.sdfd, "reference", ["--mesh-dir", mesh_dir], tmp)
    procs, lb, pg = [ref], None, pgserver.PgServer()
    try:
        pg.start()
        ref.start()
        sizes, budget = prepare(a, tmp, ref)
        replicas = [Sdfd(a.sdfd, f"replica{i}", ["--catalog", pg.uri, "--replica-id",
                                                 f"replica{i}",
                                                 "--max-resident-bytes", str(budget)], tmp)
                    for i in range(a.replicas)]
        procs += replicas
        for p in replicas:
            p.start()
        http_port, bin_port = free_ports(2)
        start = start_haproxy if a.lb == "haproxy" else start_nginx
        lb = start(tmp, a.mode, replicas, http_port, bin_port)
        lb_url = f"http://127.0.0.1:{http_port}"
        wait_for("the balancer", lambda: get(lb_url + "/v1/meshes") == 200)
        staleness, store_problems = upload_and_check(a, lb_url, replicas, ref, mesh_dir)
        binary_ok = check_binary(bin_port, ref, names[0])
        reqs = loadgen.make_requests(names[:-1], a.requests, volumes=names[-1:])
        loadgen.fetch_expected(ref.url, reqs)
        bin_items = binary_items(a, names, sizes)
        langs = worker_languages(a)
        bin_reqs = loadgen.make_binary_requests(
            [names[m] for m in bin_items if m < n - 1], a.bin_requests, len(langs),
            volumes=[names[m] for m in bin_items if m == n - 1])
        loadgen.fetch_binary_expected("127.0.0.1", ref.bin_port, bin_reqs)
        external = [(w, lang, loadgen.write_manifest(bin_reqs[w], tmp, f"worker{w}"))
                    for w, lang in enumerate(langs) if lang != "python"]
        ev = run_load(a, lb_url, bin_port, replicas, reqs, bin_reqs[:a.bin_workers], n,
                      external)
        ev["bin_items"] = bin_items
    finally:
        if lb:
            lb.terminate()
            lb.wait(timeout=10)
        for p in procs:
            p.stop()
        pg.stop()
        pg.cleanup()
    return judge(a, tmp, replicas, ev, n, names, budget, sizes, staleness,
                 store_problems, binary_ok)


def worker_languages(a):
    """Binary worker w's client: the Python workers first, then JS, then C."""
    return ["python"] * a.bin_workers + ["js"] * a.js_workers + ["c"] * a.c_workers


def last_replica(replicas, workers, t0, t):
    """binary worker -> the replica that answered its last query before t (its connection's)."""
    last = {}
    for i, r in enumerate(replicas):
        for ts, points in r.served_binary(t0):
            w = points % workers
            if ts < t and (w not in last or ts > last[w][0]):
                last[w] = (ts, i)
    return {w: i for w, (_, i) in last.items()}


def per_language(a, ev):
    """{language: its binary workers' sent, answered, lost and mismatched}, every worker's
    connections, and the completion times of every answer."""
    stats, counters = ev["binary"]
    langs = worker_languages(a)
    report = {"python": {"workers": a.bin_workers, "sent": stats.sent, "answered": stats.ok,
                         "lost": stats.failed, "mismatched": stats.mismatched,
                         "errors": [e for _, e in stats.errors[:3]]}}
    connects = [c.get("connects", 1) for c in counters]
    resent = [c.get("resent", 0) for c in counters]
    done = list(stats.done_at)
    for w in range(a.bin_workers, len(langs)):
        lang, t = ev["external"][w]
        r = report.setdefault(lang, {"workers": 0, "sent": 0, "answered": 0, "lost": 0,
                                     "mismatched": 0, "errors": []})
        r["workers"] += 1
        for key, theirs in (("sent", "sent"), ("answered", "ok"), ("lost", "failed"),
                            ("mismatched", "mismatched")):
            r[key] += t[theirs]
        r["errors"] += t["errors"][:3]
        connects.append(t["connects"])
        resent.append(t["resent"])
        done += t["done_at"]
    return report, connects, resent, done


def judge_binary(a, replicas, ev):
    """The binary load's report and problems: nothing lost or different from any client, and
    every worker whose replica died or drained under it reconnected."""
    kill, term = ev["kill"], ev["term"]
    workers = len(worker_languages(a))
    langs, connects, resent, done = per_language(a, ev)
    hit = {w: 0 for w in range(workers)}
    on = {}
    for what, i, t in (("killed", kill, ev["t_kill"]), ("terminated", term, ev["t_term"])):
        on[what] = sorted(w for w, r in last_replica(replicas, workers, ev["t0"],
                                                     t).items() if r == i)
        for w in on[what]:
            hit[w] += 1
    reconnects = [c - 1 for c in connects]
    report = {"languages": langs, "workers": workers,
              "ok_after_kill": sum(t > ev["t_kill"] for t in done),
              "ok_after_term": sum(t > ev["t_term"] for t in done),
              "reconnects": reconnects, "resent": resent,
              "on_killed": on["killed"], "on_terminated": on["terminated"]}
    problems = []
    for lang, r in langs.items():
        if r["lost"] or r["mismatched"]:
            problems.append(f"binary ({lang}): {r['lost']} lost, {r['mismatched']} mismatched "
                            f"answers: {r['errors'][:2]}")
        if r["answered"] == 0:
            problems.append(f"binary ({lang}): no answer")
    if len(done) < 20 or report["ok_after_kill"] == 0 or report["ok_after_term"] == 0:
        problems.append("the binary load did not run across both events")
    for what in on:
        if not on[what]:
            problems.append(f"binary: no worker's connection was on the {what} replica")
    for w, n in hit.items():
        if reconnects[w] < n:
            problems.append(f"binary worker {w}: {reconnects[w]} reconnects, but its replica "
                            f"went away {n} times")
    return report, problems


def judge(a, tmp, replicas, ev, n, names, budget, sizes, staleness, store_problems, binary_ok):
    """The report and its problems, from what scenario() saw and the logs."""
    stats, kill, term = ev["stats"], ev["kill"], ev["term"]
    t0, t_kill, t_term = ev["t0"], ev["t_kill"], ev["t_term"]
    drain_log = open(replicas[term].logs[-1]).read()
    windows = {i: [] for i in range(len(replicas))}
    windows[kill].append((t_kill, ev["t_ready"] + RECOVERY_SECONDS))
    windows[term].append((t_term, float("inf")))
    done = stats.done_at
    report = {
        "lb": a.lb, "mode": a.mode, "replicas": a.replicas,
        **{k: v for k, v in stats.summary().items()},
        "ok_after_kill": sum(t > t_kill for t in done),
        "ok_after_term": sum(t > t_term for t in done),
        "killed": kill, "restart_ready_s": round(ev["t_ready"] - t_kill, 3),
        "terminated": term, "term_exit": ev["term_rc"],
        "drain_s": round(ev["t_exit"] - t_term, 3), "binary_equal": binary_ok,
        "lb_retried": lb_retries(tmp, a.lb), "seconds": round(ev["t_end"] - t0, 1),
        "items_bytes": sum(sizes.values()), "budget_bytes": budget, **staleness,
    }
    problems = list(store_problems) + ev["written_problems"]
    report["written_acknowledged"] = sum(ok for h in ev["written"].values() for _, ok in h)
    report["written_unknown"] = sum(not ok for h in ev["written"].values() for _, ok in h)
    if stats.failed or stats.mismatched:
        problems.append(f"{stats.failed} failed, {stats.mismatched} mismatched requests")
    if stats.ok < 100 or report["ok_after_kill"] == 0 or report["ok_after_term"] == 0:
        problems.append("the load did not run across both events")
    if ev["t_end"] < ev["t_exit"]:
        problems.append("the load ended before the drain")
    if ev["term_rc"] != 0 or "SIGTERM: draining" not in drain_log or '"stopped"' not in drain_log:
        problems.append(f"the SIGTERMed replica exited {ev['term_rc']} or did not log its drain")
    if not binary_ok:
        problems.append("a binary query through the balancer differed from the reference")
    report["binary"], bp = judge_binary(a, replicas, ev)
    problems += bp
    problems += check_survivors(replicas, n, t0, t_kill, kill)
    owner = {}
    if a.mode == "hash":
        hp, owner = check_hash(replicas, n, t0, t_kill, t_term, windows)
        problems += hp
        report["owner"] = {names[m]: o for m, o in owner.items()}
    moved, sp = store_checks(a, replicas, ev, n, owner, budget)
    problems += sp
    report["loads_evictions_before_kill"] = moved
    report["peak_rss_mb"] = [round(r / 2**20, 1) if r else None for r in ev["rss"]]
    served = [len(r.served(t0)) for r in replicas]
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
    ap.add_argument("--bin-workers", type=int, default=4,
                    help="binary-protocol workers of the Python client, one connection each "
                    "(with the JS and C ones, at least the replicas)")
    ap.add_argument("--js-workers", type=int, default=1,
                    help="binary-protocol workers of the JS client (node), one process each")
    ap.add_argument("--c-workers", type=int, default=1,
                    help="binary-protocol workers of libsdfclient (sdfc-load), one process each")
    ap.add_argument("--node", default="node", help="node 18+, for the JS workers")
    ap.add_argument("--sdfc-load", default=os.path.join(ROOT, "build", "tests", "sdfc-load"),
                    help="the C worker (built from tests/clients/sdfc_load.c)")
    ap.add_argument("--bin-requests", type=int, default=12,
                    help="distinct binary requests per worker")
    ap.add_argument("--max-resident-bytes", type=int, default=-1,
                    help="the replicas' budget (default: under the sum of the items, over it "
                    "less any one; 0: none)")
    ap.add_argument("--rounds", type=int, default=12,
                    help="queries of the baked mesh and volume through the balancer")
    ap.add_argument("--keep", action="store_true",
                    help="keep the logs' folder (kept anyway when the test fails)")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="sdfd-failover-")
    report = scenario(a, tmp)
    print(json.dumps(report))
    if a.keep or report["problems"]:
        print(f"logs: {tmp}")
    else:
        shutil.rmtree(tmp, ignore_errors=True)
    if report["problems"]:
        print("FAIL: " + "; ".join(report["problems"]))
        return 1
    print(f"ok: {a.lb} {a.mode}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
