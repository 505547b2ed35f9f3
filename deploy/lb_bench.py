#!/usr/bin/python3
"""lb_bench.py - what a load balancer of deploy/lb/ costs: sdfd's throughput through HAProxy
and nginx (each routing mode) next to the same sdfd direct, in one run.

One sdfd serves MESH; each balancer runs deploy/lb/'s configuration with only its addresses
changed (failover.py's start_haproxy / start_nginx) and both of its server lines on that one
sdfd, so a row's ratio is the balancer's own cost, not a second replica's CPUs. Workloads, by
build/tests/bench/sdfd-bench on the mesh's band points: one request of N points, and 64
concurrent clients of 1,000 points each until N are done; over HTTP (octet-stream bodies) and
the binary protocol (the balancers' TCP streams, which do not depend on the routing mode).
Each round runs every (workload, path) once, direct first; the table shows the best of the
rounds per row, so a row and its direct base see the same moments of a shared machine.

    /usr/bin/python3 deploy/lb_bench.py [--mesh tests/data/refined_elephant.off] [--n 1000000]
                                        [--rounds 3]

Needs build/ (release; or the build directory BUILD names) with sdfd and sdfd-bench, haproxy and nginx (Debian's haproxy,
nginx-light, libnginx-mod-stream).
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
BUILD = os.environ.get("BUILD", os.path.join(ROOT, "build"))
sys.path.insert(0, HERE)
import failover  # noqa: E402

WORKLOADS = (  # label, sdfd-bench form, clients
    ("1 x N, HTTP octet-stream", "octet", 1),
    ("64 x 1000, HTTP octet-stream", "octet", 64),
    ("1 x N, binary", "binary", 1),
    ("64 x 1000, binary", "binary", 64),
)


def start_balancers(tmp, backend):
    """{path label: (http port, binary port)} of the four balancers in front of `backend`."""
    paths, procs = {}, []
    for lb in ("haproxy", "nginx"):
        for mode in ("leastconn", "hash"):
            http, binary = failover.free_ports(2)
            where = os.path.join(tmp, f"{lb}-{mode}")
            os.mkdir(where)
            start = failover.start_haproxy if lb == "haproxy" else failover.start_nginx
            procs.append(start(where, mode, [backend, backend], http, binary))
            paths[f"{lb} {mode}"] = (http, binary)
    for http, _ in paths.values():
        failover.wait_for("a balancer",
                          lambda: failover.get(f"http://127.0.0.1:{http}/readyz") == 200)
    return paths, procs


def bench(a, http, binary, form, clients):
    cmd = [os.path.join(BUILD, "tests", "bench", "sdfd-bench"), a.mesh, "--name", "m",
           "--http", f"127.0.0.1:{http}", "--bin", f"127.0.0.1:{binary}", "--form", form,
           "--n", str(a.n), "--clients", str(clients)]
    if clients == 1:
        cmd += ["--repeat", "2"]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    for line in out.splitlines():
        if line.startswith("throughput:"):
            return float(line.split()[1])
    raise RuntimeError(f"sdfd-bench printed no throughput:\n{out}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", default=os.path.join(ROOT, "tests", "data",
                                                   "refined_elephant.off"))
    ap.add_argument("--n", type=int, default=1000000)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    for tool in ("haproxy", "nginx"):
        if not shutil.which(tool):
            sys.exit(f"lb_bench.py: {tool} is not installed")
    tmp = tempfile.mkdtemp(prefix="sdfd-lb-bench-")
    sdfd = failover.Sdfd(os.path.join(BUILD, "server", "sdfd"), "sdfd",
                         ["--mesh", f"m={a.mesh}", "--threads", "0"], tmp)
    procs = []
    try:
        sdfd.start()
        paths, procs = start_balancers(tmp, sdfd)
        paths = {"direct": (sdfd.http_port, sdfd.bin_port), **paths}
        best = {}
        for _ in range(a.rounds):
            for label, form, clients in WORKLOADS:
                for path, (http, binary) in paths.items():
                    if form == "binary" and path.endswith(" hash"):
                        continue  # the TCP stream is the same in both modes
                    v = bench(a, http, binary, form, clients)
                    best[label, path] = max(best.get((label, path), 0.0), v)
        print(f"mesh {os.path.basename(a.mesh)}, N = {a.n}, best of {a.rounds} rounds\n")
        print("| workload | path | Mq/s | vs direct |")
        print("| --- | --- | ---: | ---: |")
        for label, path in best:
            v, base = best[label, path], best[label, "direct"]
            path_label = path.replace(" leastconn", "") if "binary" in label else path
            print(f"| {label} | {path_label} | {v:.2f} | {v / base:.2f} |")
    finally:
        for p in procs:
            p.terminate()
            p.wait()
        sdfd.stop()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
