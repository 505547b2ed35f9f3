#!/usr/bin/env python3
"""loadgen.py - a bounded, concurrent load of sdfd queries whose every answer is checked.

It makes a fixed set of query requests (JSON and octet-stream bodies, 1 to ~65000 points, modes
signed, distance, gradient and closest on meshes, value and gradient on volumes, spread over the
given meshes and volumes), asks a reference sdfd
for each answer once, then sends them at random from several threads at once to a target (a
load balancer, say) and compares every answer with the reference's byte for byte. A request
fails if it raises, or answers anything but 200, or answers other bytes. The load stops by
itself after --seconds or --max-requests, whichever comes first.

The names are numbered meshes first, then volumes; the number of points of a request for name i
of M is i modulo M, so a replica's request log (its "points" field) tells which mesh or volume
each query it served was for (deploy/failover.py uses that to check hashing).

The same for the binary protocol (make_binary_requests, fetch_binary_expected, run_binary):
each worker holds one sdfclient.BinaryClient (clients/python) for the whole run and sends its
own requests (1 to ~65000 points, the same modes; a quarter of them three at a time with
query_many), checked against the reference's binary answers. write_manifest hands a worker's
requests to the JS and C clients' workers (clients/js/test/loadworker.js,
tests/clients/sdfc_load.c), which do the same with their own client. Worker w of W sends point counts
that are w modulo W, so a replica's log tells whose connection it served. A request fails
(an answer is lost) if the client raises; the client itself sends a query once more on a new
connection when its connection dies or the server refuses it as shutting down, and the run
reports each worker's reconnects.

    python3 deploy/loadgen.py --target http://127.0.0.1:8080 --reference http://127.0.0.1:18080 \\
        --meshes demo --workers 6 --seconds 10

Standard library, numpy and clients/python (sdfclient).
"""
import argparse
import http.client
import json
import os
import random
import sys
import threading
import time
import urllib.parse

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                "clients", "python"))
import sdfclient  # noqa: E402

MODES = ("signed", "distance", "gradient", "closest")
VOLUME_MODES = ("value", "gradient")
JSON_MAX_POINTS = 3000  # a JSON body of this many points is ~150 KB
OCTET_MAX_POINTS = 65000  # 780 KB: under haproxy's and nginx's 1 MiB retry buffers


class Request:
    """One query: where it goes, its body and headers."""

    def __init__(self, name_index, name, path, body, content_type):
        self.name_index, self.name, self.path = name_index, name, path
        self.body, self.content_type = body, content_type
        self.expected = None

    def send(self, conn):
        """Sends on an http.client connection; returns (status, body bytes)."""
        conn.request("POST", self.path, body=self.body,
                     headers={"Content-Type": self.content_type, "Accept": self.content_type})
        r = conn.getresponse()
        return r.status, r.read()


def point_count(rng, limit, name_index, n_names):
    """Log-uniform in 1..limit, then moved to the residue name_index modulo n_names."""
    n = int(np.exp(rng.uniform(0, np.log(limit))))
    n = n - n % n_names + name_index
    return n if n > 0 else n + n_names


def make_requests(meshes, count, seed=1, volumes=()):
    """`count` requests, name by name in turn (meshes, then volumes), half JSON and half
    octet-stream."""
    rng = np.random.default_rng(seed)
    names = [("meshes", m, MODES) for m in meshes] + [("volumes", v, VOLUME_MODES)
                                                      for v in volumes]
    out = []
    for k in range(count):
        i = k % len(names)
        kind, name, modes = names[i]
        octet = (k // len(names)) % 2 == 1
        n = point_count(rng, OCTET_MAX_POINTS if octet else JSON_MAX_POINTS, i, len(names))
        pts = rng.uniform(-1.5, 1.5, (n, 3)).astype(np.float32)
        mode = modes[rng.integers(len(modes))]
        base = f"/v1/{kind}/" + urllib.parse.quote(name) + "/query"
        if octet:
            out.append(Request(i, name, base + "?mode=" + mode,
                               pts.astype("<f4").tobytes(), "application/octet-stream"))
        else:
            body = json.dumps({"points": pts.tolist(), "mode": mode}).encode()
            out.append(Request(i, name, base, body, "application/json"))
    return out


def connect(url, timeout):
    u = urllib.parse.urlsplit(url)
    return http.client.HTTPConnection(u.hostname, u.port or 80, timeout=timeout)


def fetch_expected(reference, requests, timeout=120):
    """Fills each request's expected answer from the reference; fails on any non-200."""
    conn = connect(reference, timeout)
    for r in requests:
        status, body = r.send(conn)
        if status != 200:
            raise RuntimeError(f"reference answered {status} to {r.path}: {body[:200]!r}")
        r.expected = body
    conn.close()


class Stats:
    def __init__(self):
        self.lock = threading.Lock()
        self.sent = self.ok = self.failed = self.mismatched = 0
        self.errors = []  # (time, description), the first few
        self.done_at = []  # completion times of the successful requests

    def record(self, t, outcome, detail=None):
        with self.lock:
            self.sent += 1
            if outcome == "ok":
                self.ok += 1
                self.done_at.append(t)
                return
            if outcome == "mismatch":
                self.mismatched += 1
            else:
                self.failed += 1
            if len(self.errors) < 20:
                self.errors.append((t, detail))

    def summary(self):
        return {"sent": self.sent, "ok": self.ok, "failed": self.failed,
                "mismatched": self.mismatched, "errors": self.errors[:5]}


def worker(target, requests, stats, deadline, budget, seed, timeout):
    rng = random.Random(seed)
    conn = connect(target, timeout)
    while time.monotonic() < deadline:
        with budget["lock"]:
            if budget["left"] <= 0:
                break
            budget["left"] -= 1
        r = requests[rng.randrange(len(requests))]
        try:
            status, body = r.send(conn)
        except (OSError, http.client.HTTPException) as e:
            stats.record(time.time(), "failed", f"{r.path} ({len(r.body)} B): {e!r}")
            conn.close()
            conn = connect(target, timeout)
            continue
        if status != 200:
            stats.record(time.time(), "failed", f"{r.path}: {status} {body[:200]!r}")
        elif body != r.expected:
            stats.record(time.time(), "mismatch", f"{r.path}: {len(body)} B differ")
        else:
            stats.record(time.time(), "ok")
    conn.close()


def run(target, requests, workers=6, seconds=20.0, max_requests=100000, timeout=60):
    """Runs the load to completion; returns the Stats."""
    stats = Stats()
    deadline = time.monotonic() + seconds
    budget = {"lock": threading.Lock(), "left": max_requests}
    threads = [threading.Thread(target=worker,
                                args=(target, requests, stats, deadline, budget, s, timeout))
               for s in range(workers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return stats


class BinaryRequest:
    """One binary-protocol query: a mesh query in `mode`, or a volume query (`mode` "value"
    or "gradient"); `expected` is its answer's arrays as bytes, by key."""

    def __init__(self, worker, kind, name, points, mode):
        self.worker, self.kind, self.name, self.points, self.mode = worker, kind, name, points, mode
        self.expected = None

    def ask(self, client):
        """The answer from a BinaryClient, as {key: bytes}."""
        if self.kind == "volumes":
            r = client.query_volume(self.name, self.points, gradient=self.mode == "gradient")
        else:
            r = client.query(self.name, self.points, mode=self.mode)
        return answer_bytes(r)


def answer_bytes(result):
    return {k: np.ascontiguousarray(v).tobytes() for k, v in result.items()}


def make_binary_requests(meshes, per_worker, workers, seed=2, volumes=()):
    """`per_worker` requests for each of `workers` workers, name by name in turn; worker w's
    point counts are w modulo `workers`. A list per worker."""
    rng = np.random.default_rng(seed)
    names = [("meshes", m, MODES) for m in meshes] + [("volumes", v, VOLUME_MODES)
                                                      for v in volumes]
    out = []
    for w in range(workers):
        mine = []
        for k in range(per_worker):
            kind, name, modes = names[k % len(names)]
            n = point_count(rng, OCTET_MAX_POINTS, w, workers)
            pts = rng.uniform(-1.5, 1.5, (n, 3)).astype(np.float32)
            mine.append(BinaryRequest(w, kind, name, pts, modes[rng.integers(len(modes))]))
        out.append(mine)
    return out


def fetch_binary_expected(host, port, per_worker, timeout=120):
    """Fills each request's expected answer from the reference's binary port."""
    client = sdfclient.BinaryClient(host, port, timeout=timeout)
    for mine in per_worker:
        for r in mine:
            r.expected = r.ask(client)
    client.close()


def result_words(expected, count):
    """A binary answer ({key: bytes}, as answer_bytes gives) as its RESULT's words in wire
    order (distance, then gradient or closest, then triangle), little-endian bytes."""
    cols = [np.frombuffer(expected[k], np.uint32).reshape(count, -1)
            for k in ("distance", "gradient", "closest", "triangle") if k in expected]
    return np.ascontiguousarray(np.hstack(cols), dtype="<u4").tobytes()


def write_manifest(requests, folder, tag):
    """One worker's requests as files for the JS and C workers (clients/js/test/loadworker.js,
    tests/clients/sdfc_load.c): a manifest of "KIND NAME MODE COUNT POINTS EXPECTED" lines,
    the points as float32 and the expected answer as its RESULT's words; the manifest's
    path."""
    lines = []
    for i, r in enumerate(requests):
        pts = os.path.join(folder, f"{tag}.{i}.f32")
        exp = os.path.join(folder, f"{tag}.{i}.words")
        with open(pts, "wb") as f:
            f.write(np.ascontiguousarray(r.points, dtype="<f4").tobytes())
        with open(exp, "wb") as f:
            f.write(result_words(r.expected, len(r.points)))
        lines.append(f"{r.kind} {r.name} {r.mode} {len(r.points)} {pts} {exp}\n")
    path = os.path.join(folder, f"{tag}.manifest")
    with open(path, "w") as f:
        f.writelines(lines)
    return path


def binary_round(client, rng, mine, batches):
    """One query, or three of one mode pipelined: [(request, answer or exception)]."""
    r = mine[rng.randrange(len(mine))]
    group = batches.get(r.mode) if r.kind == "meshes" else None
    if not group or rng.random() >= 0.25:
        try:
            return [(r, r.ask(client))]
        except (OSError, sdfclient.SdfError) as e:
            return [(r, e)]
    rs = [r] + [group[rng.randrange(len(group))] for _ in range(2)]
    try:
        got = client.query_many([(q.name, q.points) for q in rs], mode=r.mode)
    except (OSError, sdfclient.SdfError) as e:
        return [(q, e) for q in rs]
    return [(q, a if isinstance(a, Exception) else answer_bytes(a)) for q, a in zip(rs, got)]


def binary_worker(where, mine, stats, deadline, budget, seed, timeout, counters):
    """One BinaryClient's share of the load; its connects and re-sends go in counters."""
    rng = random.Random(seed)
    batches = {}
    for r in mine:
        if r.kind == "meshes":
            batches.setdefault(r.mode, []).append(r)
    client = None
    while time.monotonic() < deadline:
        if client is None:
            try:
                client = sdfclient.BinaryClient(*where, timeout=timeout)
            except OSError as e:
                stats.record(time.time(), "failed", f"connect: {e!r}")
                time.sleep(0.1)
                continue
        with budget["lock"]:
            if budget["left"] <= 0:
                break
            budget["left"] -= 1
        for r, got in binary_round(client, rng, mine, batches):
            what = f"{r.kind}/{r.name} {r.mode} ({len(r.points)} points)"
            if isinstance(got, Exception):
                stats.record(time.time(), "failed", f"{what}: {got!r}")
            elif got != r.expected:
                stats.record(time.time(), "mismatch", f"{what}: the answer differs")
            else:
                stats.record(time.time(), "ok")
    if client is not None:
        counters.update(connects=client.connects, resent=client.resent)
        client.close()


def run_binary(where, per_worker, seconds=20.0, max_requests=100000, timeout=60):
    """Runs the binary load (one worker per list of requests) to completion; returns the
    Stats and each worker's {"connects", "resent"}."""
    stats = Stats()
    deadline = time.monotonic() + seconds
    budget = {"lock": threading.Lock(), "left": max_requests}
    counters = [{} for _ in per_worker]
    threads = [threading.Thread(target=binary_worker,
                                args=(where, mine, stats, deadline, budget, 100 + w, timeout,
                                      counters[w]))
               for w, mine in enumerate(per_worker)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return stats, counters


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--target", required=True, help="URL the load goes to")
    ap.add_argument("--reference", required=True,
                    help="URL of an sdfd serving the same meshes and volumes")
    ap.add_argument("--meshes", default="demo", help="comma-separated mesh names")
    ap.add_argument("--volumes", default="", help="comma-separated volume names")
    ap.add_argument("--requests", type=int, default=48, help="distinct requests made")
    ap.add_argument("--workers", type=int, default=6, help="concurrent connections")
    ap.add_argument("--seconds", type=float, default=10)
    ap.add_argument("--max-requests", type=int, default=100000)
    a = ap.parse_args()
    volumes = [v for v in a.volumes.split(",") if v]
    reqs = make_requests([m for m in a.meshes.split(",") if m], a.requests, volumes=volumes)
    fetch_expected(a.reference, reqs)
    s = run(a.target, reqs, a.workers, a.seconds, a.max_requests)
    print(json.dumps(s.summary()))
    return 0 if s.failed == 0 and s.mismatched == 0 and s.ok > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
