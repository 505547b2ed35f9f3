#!/usr/bin/python3
"""catalog_bench.py - what --catalog (PostgreSQL) costs, against the single-node file store and
memory, on one machine (docs/performance.md, "The catalog"). A measurement, not a test:

  - PUT latency: N uploads of fandisk (each with other bytes: a comment line numbers it), p50
    and p99, to an sdfd with --data-dir and to one with --catalog;
  - cross-replica visibility: two replicas on one catalog; after a PUT on A is answered, how
    long until B answers the new version (its triangle count), N times, p50 and p99;
  - query throughput: T threads of the Python client, each asking 4096-point queries of
    fandisk for S seconds, against an sdfd with --catalog and one that loaded the mesh itself
    (--mesh), in the same run: points/s and the ratio.

PostgreSQL is the test's own (tests/server/pgserver.py: Debian's postgresql, fsync off, on
loopback). Prints Markdown lines.

    SDFD=build/server/sdfd /usr/bin/python3 tests/bench/catalog_bench.py [--n 50] [--seconds 3]
"""
import argparse
import http.client
import json
import os
import shutil
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "server"))
sys.path.insert(0, os.path.join(HERE, "..", "..", "clients", "python"))
import numpy as np  # noqa: E402
import sdfclient  # noqa: E402
from harness import DATA, Server  # noqa: E402
from meshgen import bipyramid  # noqa: E402
from pgserver import PgServer  # noqa: E402

FANDISK = os.path.join(DATA, "fandisk.off")


def percentile(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(q * (len(xs) - 1))))]


def put(conn, name, body):
    conn.request("PUT", "/v1/meshes/" + name, body, {"Content-Type": "application/octet-stream"})
    r = conn.getresponse()
    r.read()
    if r.status not in (200, 201):
        raise RuntimeError(f"PUT {name}: {r.status}")


def triangles(conn, name):
    conn.request("GET", "/v1/meshes/" + name)
    r = conn.getresponse()
    body = r.read()
    return json.loads(body)["triangles"] if r.status == 200 else None


def variants(n):
    """fandisk's bytes, n times, each with a numbered comment line (other bytes, same mesh)."""
    base = open(FANDISK, "rb").read()
    head, rest = base.split(b"\n", 1)
    return [head + b"\n# variant %d\n" % i + rest for i in range(n)]


def put_latency(server, bodies):
    conn = http.client.HTTPConnection("127.0.0.1", server.ports["http"], timeout=60)
    times = []
    for i, body in enumerate(bodies):
        t = time.perf_counter()
        put(conn, "m%d" % (i % 4), body)
        times.append(time.perf_counter() - t)
    conn.close()
    return times


def visibility(a, b, n):
    """Seconds from A's answer to a PUT until B answers the new version."""
    ca = http.client.HTTPConnection("127.0.0.1", a.ports["http"], timeout=60)
    cb = http.client.HTTPConnection("127.0.0.1", b.ports["http"], timeout=60)
    out = []
    for i in range(n):
        body = open(FANDISK, "rb").read() if i % 2 else bipyramid(3 + i)
        want = 12946 if i % 2 else 2 * (3 + i)
        put(ca, "vis", body)
        t = time.perf_counter()
        while triangles(cb, "vis") != want:
            if time.perf_counter() - t > 10:
                raise RuntimeError("B never answered the new version")
        out.append(time.perf_counter() - t)
    return out




def throughput(server, name, threads, seconds):
    points = np.random.default_rng(1).uniform(-0.6, 0.6, (4096, 3)).astype(np.float32)
    done = [0] * threads
    stop = time.perf_counter() + seconds

    def work(w):
        c = sdfclient.Client(server.url)
        while time.perf_counter() < stop:
            c.query(name, points, form="octet")
            done[w] += len(points)
        c.close()
    ts = [threading.Thread(target=work, args=(w,)) for w in range(threads)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    return sum(done) / seconds


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--seconds", type=float, default=3)
    ap.add_argument("--threads", type=int, default=4)
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="sdfd-catalog-bench-")
    pg = PgServer()
    pg.start()
    servers = []
    try:
        bodies = variants(a.n)
        f = Server("--data-dir", os.path.join(tmp, "store"))
        servers.append(f)
        file_times = put_latency(f, bodies)
        c1 = Server("--catalog", pg.uri)
        c2 = Server("--catalog", pg.uri)
        servers += [c1, c2]
        cat_times = put_latency(c1, bodies)
        vis = visibility(c1, c2, a.n)
        m = Server("--mesh", "part=" + FANDISK)
        servers.append(m)
        sdfclient.Client(c1.url).upload("part", FANDISK)
        q_mem = throughput(m, "part", a.threads, a.seconds)
        q_cat = throughput(c2, "part", a.threads, a.seconds)
        q_mem2 = throughput(m, "part", a.threads, a.seconds)  # both sides twice: drift shows
        q_cat2 = throughput(c2, "part", a.threads, a.seconds)
    finally:
        for s in servers:
            s.stop()
        pg.stop()
        pg.cleanup()
        shutil.rmtree(tmp, ignore_errors=True)
    ms = lambda xs, q: 1e3 * percentile(xs, q)  # noqa: E731
    print("| store | PUT p50 ms | PUT p99 ms |")
    print("| --- | ---: | ---: |")
    print(f"| --data-dir | {ms(file_times, .5):.1f} | {ms(file_times, .99):.1f} |")
    print(f"| --catalog | {ms(cat_times, .5):.1f} | {ms(cat_times, .99):.1f} |")
    print()
    print(f"Cross-replica visibility (PUT answered on A until B answers it, {a.n} writes): "
          f"p50 {ms(vis, .5):.1f} ms, p99 {ms(vis, .99):.1f} ms, max {ms(vis, 1):.1f} ms.")
    print()
    print("| server | query Mpoints/s (two runs) |")
    print("| --- | --- |")
    print(f"| --mesh (memory) | {q_mem / 1e6:.2f} {q_mem2 / 1e6:.2f} |")
    print(f"| --catalog | {q_cat / 1e6:.2f} {q_cat2 / 1e6:.2f} |")
    print()
    print(f"Query throughput with --catalog over memory: "
          f"{(q_cat + q_cat2) / (q_mem + q_mem2):.2f}x")


if __name__ == "__main__":
    main()
