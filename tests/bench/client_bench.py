#!/usr/bin/python3
"""client_bench.py - the Python client's (clients/python/sdfclient) throughput on one request
of every point, for tests/bench/server-compare.sh, next to the in-process library on the same
points. Not a test: it asserts nothing but that the server answered.

  client_bench.py POINTS.npy --form binary|octet|json [--bin HOST:PORT] [--http URL]
                  [--name NAME] [--repeat R] [--out OUT.f32]

POINTS.npy is (N, 3) float32 (sdf-bench --points-out writes it). One query of all N points,
signed, sign auto, on mesh NAME (default demo): `binary` through BinaryClient, `octet` and
`json` through Client in that body form. Sent once untimed, then R times (default 2), best
reported. Timed is what a program pays: from the numpy array of points to the answer's
arrays. --out writes the distances as raw little-endian float32 (the data of sdf-bench
--out's .npy), to be compared byte for byte. Also printed: the client's CPU time (this
process's, user and system) per timed request, which the machine's other work inflates far
less than the wall time. The last line printed is `throughput: X Mq/s`.
Needs numpy (Debian's python3-numpy, hence /usr/bin/python3)."""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..",
                                "clients", "python"))
import sdfclient  # noqa: E402  (the checkout's client, not an installed one)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("points")
    ap.add_argument("--form", choices=["binary", "octet", "json"], required=True)
    ap.add_argument("--bin", default="127.0.0.1:9090")
    ap.add_argument("--http", default="http://127.0.0.1:8080")
    ap.add_argument("--name", default="demo")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out")
    a = ap.parse_args()
    points = np.load(a.points)
    if points.dtype != np.float32 or points.ndim != 2 or points.shape[1] != 3:
        sys.exit(f"client_bench.py: {a.points}: expected a float32 (N, 3) array")
    if a.form == "binary":
        host, port = a.bin.rsplit(":", 1)
        client = sdfclient.BinaryClient(host, int(port))
        def query() -> sdfclient.Result:
            return client.query(a.name, points)
    else:
        http = sdfclient.Client(a.http)
        def query() -> sdfclient.Result:
            return http.query(a.name, points, form=a.form)
    best, cpu, repeat = float("inf"), 0.0, max(a.repeat, 1)
    for i in range(-1, repeat):  # i = -1: the untimed warm-up
        t0, c0 = time.perf_counter(), time.process_time()
        answer = query()
        t = time.perf_counter() - t0
        if i >= 0:
            best = min(best, t)
            cpu += time.process_time() - c0
    n = len(points)
    if answer["distance"].shape != (n,):
        sys.exit(f"client_bench.py: the answer holds {answer['distance'].shape} values, not {n}")
    if a.out:
        answer["distance"].astype("<f4").tofile(a.out)
    print(f"points: {n} client: sdfclient.py form: {a.form} requests: 1")
    print(f"client cpu ms: {1e3 * cpu / repeat:.1f}")
    print(f"seconds: {best:.4f}")
    print(f"throughput: {n / best / 1e6:.4f} Mq/s")


if __name__ == "__main__":
    main()
