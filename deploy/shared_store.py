#!/usr/bin/env python3
"""shared_store.py - what sdfd replicas sharing one catalog (--catalog) must show behind a
balancer.

deploy/failover.py runs these checks before its load, and deploy/test.sh's pod part runs them
through the pod's HAProxy (`python3 deploy/shared_store.py --lb URL --replica URL ...`):
  - meshes uploaded (PUT) and a volume baked (POST .../bake) through the balancer, the job
    polled through it until done;
  - the mesh and the volume queried through the balancer again and again, then on every replica
    directly (a query, the volume's raw data, the job's record), every answer bit-equal to a
    reference sdfd that loaded the same files itself and baked the same volume;
  - a mesh replaced through the balancer: every replica answers the old bits or the new ones,
    never anything else, and the new ones within the staleness window (docs/api.md, "Catalog
    (PostgreSQL)"); then deleted through the balancer: every replica answers 404 within it too;
  - (deploy/failover.py) a writer's PUTs and DELETEs through the balancer while replicas are
    killed and drained: afterwards every replica serves, for each name, its last acknowledged
    write (or a later one whose answer was lost), all of them the same.
Each answer from a replica that has not seen an item yet makes it load the item from the
catalog.

Standard library and numpy only.
"""
import argparse
import json
import os
import sys
import time
import urllib.error
import urllib.request

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests",
                                "server"))
from meshgen import bipyramid  # noqa: E402

# docs/api.md: a write is seen by the other replicas within tens of milliseconds, plus a reload;
# this allows a loaded two-core machine's scheduling, and more is a fault.
STALENESS_LIMIT_S = 1.0
POINTS = np.random.default_rng(11).uniform(-1.5, 1.5, (3000, 3)).astype("<f4")


def call(url, method="GET", body=None, ctype=None, token=None, timeout=60):
    """(status, body bytes); a connection failure raises."""
    headers = {}
    if ctype:
        headers["Content-Type"] = ctype
    if token:
        headers["Authorization"] = "Bearer " + token
    req = urllib.request.Request(url, body, headers, method=method)
    try:
        with urllib.request.urlopen(req, timeout=timeout) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def upload(url, name, path, token):
    fmt = os.path.splitext(path)[1][1:]
    with open(path, "rb") as f:
        return call(f"{url}/v1/meshes/{name}?format={fmt}", "PUT", f.read(),
                    "application/octet-stream", token)


def bake(url, mesh, volume, resolution, token, seconds=120):
    """Bakes through `url` and polls the job there until it ends; (job id, final job)."""
    body = json.dumps({"volume": volume, "resolution": resolution}).encode()
    status, answer = call(f"{url}/v1/meshes/{mesh}/bake", "POST", body, "application/json",
                          token)
    if status != 202:
        raise RuntimeError(f"bake of {mesh} at {url}: {status} {answer[:200]!r}")
    job = json.loads(answer)["id"]
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        status, answer = call(f"{url}/v1/jobs/{job}")
        state = json.loads(answer) if status == 200 else {"state": f"HTTP {status}"}
        if state.get("state") in ("done", "failed", "canceled"):
            return job, state
        time.sleep(0.05)
    raise RuntimeError(f"bake {job} at {url} did not end in {seconds} s")


def mesh_query(url, name):
    return call(f"{url}/v1/meshes/{name}/query?mode=gradient", "POST", POINTS.tobytes(),
                "application/octet-stream")


def volume_query(url, name):
    return call(f"{url}/v1/volumes/{name}/query?mode=gradient", "POST", POINTS.tobytes(),
                "application/octet-stream")


def volume_data(url, name):
    return call(f"{url}/v1/volumes/{name}/data?format=raw")


def resident_bytes(url, meshes, volumes):
    """name -> the bytes sdfd counts against --max-resident-bytes (docs/api.md, "Memory")."""
    out = {}
    for m in meshes:
        r = json.loads(call(f"{url}/v1/meshes/{m}")[1])
        out[m] = r["index_bytes"] + 12 * r["vertices"] + 12 * r["triangles"]
    for v in volumes:
        out[v] = json.loads(call(f"{url}/v1/volumes/{v}")[1])["bytes"]
    return out


def same(got, want, what, problems):
    """Appends a problem unless `got` is a 200 with `want`'s bytes."""
    if got[0] != 200 or got[1] != want[1]:
        problems.append(f"{what}: {got[0]}, {len(got[1])} B, not the reference's "
                        f"{len(want[1])} B")


def check_answers(lb, replicas, ref, mesh, volume, job, rounds):
    """The mesh and the volume through the balancer `rounds` times, then on each replica."""
    problems = []
    want_mesh, want_volume = mesh_query(ref, mesh), volume_query(ref, volume)
    want_data = volume_data(ref, volume)
    for i in range(rounds):
        same(mesh_query(lb, mesh), want_mesh, f"balancer, mesh {mesh}, round {i}", problems)
        same(volume_query(lb, volume), want_volume, f"balancer, volume {volume}, round {i}",
             problems)
    for r in replicas:
        same(mesh_query(r, mesh), want_mesh, f"{r}: mesh {mesh}", problems)
        same(volume_query(r, volume), want_volume, f"{r}: volume {volume}", problems)
        same(volume_data(r, volume), want_data, f"{r}: volume {volume} raw data", problems)
        status, answer = call(f"{r}/v1/jobs/{job}")
        if status != 200 or json.loads(answer).get("state") != "done":
            problems.append(f"{r}: job {job}: {status} {answer[:120]!r}")
    return problems


def wait_all(replicas, test, what, problems):
    """Polls test(replica) on every replica until each is True; the longest wait in s."""
    t0 = time.monotonic()
    pending = set(replicas)
    while pending and time.monotonic() - t0 < 2 * STALENESS_LIMIT_S:
        for r in sorted(pending):
            verdict = test(r)
            if verdict is True:
                pending.discard(r)
            elif verdict is not False:
                problems.append(f"{r}: {what}: {verdict}")
                return None
        time.sleep(0.02)
    waited = time.monotonic() - t0
    if pending or waited > STALENESS_LIMIT_S:
        problems.append(f"{what}: {sorted(pending)} still stale after {waited:.2f} s")
    return round(waited, 3)


def check_staleness(lb, replicas, ref, token, old, new, name="swap"):
    """Replaces and deletes `name` through the balancer (`old`, `new`: (mesh file, the
    reference's name for it)); {"replace_s", "delete_s"} and problems."""
    problems = []
    want_old, want_new = mesh_query(ref, old[1]), mesh_query(ref, new[1])
    if upload(lb, name, old[0], token)[0] not in (200, 201):
        return {}, [f"PUT {name} through the balancer failed"]
    for r in replicas:  # each replica has the old version in memory
        same(mesh_query(r, name), want_old, f"{r}: {name} before the replacement", problems)
    if upload(lb, name, new[0], token)[0] != 200:
        return {}, problems + [f"the replacing PUT of {name} did not answer 200"]

    def replaced(r):
        got = mesh_query(r, name)
        if got[0] == 200 and got[1] in (want_old[1], want_new[1]):
            return got[1] == want_new[1]
        return f"answered {got[0]}, {len(got[1])} B: neither the old version nor the new"

    out = {"replace_s": wait_all(replicas, replaced, f"the replaced {name}", problems)}
    if call(f"{lb}/v1/meshes/{name}", "DELETE", token=token)[0] != 204:
        return out, problems + [f"DELETE {name} through the balancer did not answer 204"]

    def deleted(r):
        got = mesh_query(r, name)
        if got[0] == 200 and got[1] == want_new[1]:
            return False
        return True if got[0] == 404 else f"answered {got[0]} after the delete"

    out["delete_s"] = wait_all(replicas, deleted, f"the deleted {name}", problems)
    return out, problems




def write_loop(lb, names, token, stop, history, seed=3):
    """PUTs (meshes of 6..80 triangles) and DELETEs of `names` through the balancer, one
    writer, until `stop` is set. history[name]: [(triangles or None, acknowledged)], in
    order; a write whose answer was lost (a killed replica) is not acknowledged."""
    rng = np.random.default_rng(seed)
    while not stop.is_set():
        name = names[rng.integers(len(names))]
        k = int(rng.integers(3, 41))
        delete = rng.random() < 0.3
        try:
            if delete:
                status = call(f"{lb}/v1/meshes/{name}", "DELETE", token=token, timeout=10)[0]
            else:
                status = call(f"{lb}/v1/meshes/{name}", "PUT", bipyramid(k),
                              "application/octet-stream", token, timeout=10)[0]
        except OSError:
            status = None
        history.setdefault(name, []).append((None if delete else 2 * k,
                                             status in (200, 201, 204)))
        time.sleep(0.02)


def check_written(replicas, history):
    """Problems unless every replica serves, for each name, its last acknowledged write or a
    later unacknowledged one, and all replicas the same (waiting out the staleness window)."""
    problems = []
    for name, h in history.items():
        last = max((i for i, (_, ok) in enumerate(h) if ok), default=-1)
        allowed = {t for t, _ in h[max(last, 0):]} | ({None} if last < 0 else set())

        def state(r):
            status, body = call(f"{r}/v1/meshes/{name}")
            return json.loads(body)["triangles"] if status == 200 else None
        deadline = time.monotonic() + 2 * STALENESS_LIMIT_S
        while True:
            seen = {r: state(r) for r in replicas}
            if len(set(seen.values())) == 1 or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        if len(set(seen.values())) != 1:
            problems.append(f"written {name}: the replicas disagree: {seen}")
        elif next(iter(seen.values())) not in allowed:
            problems.append(f"written {name}: served {seen}, but the acknowledged state is one "
                            f"of {sorted(allowed, key=str)} (last writes {h[-4:]})")
    if sum(ok for h in history.values() for _, ok in h) < 10:
        problems.append("the writer had fewer than 10 writes acknowledged")
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lb", required=True, help="the balancer's URL")
    ap.add_argument("--replica", action="append", required=True, help="a replica's URL")
    ap.add_argument("--reference", required=True,
                    help="an sdfd with the meshes loaded from files, no catalog")
    ap.add_argument("--mesh", required=True, help="NAME=FILE: uploaded and baked")
    ap.add_argument("--swap", nargs=2, required=True, metavar="NAME=FILE",
                    help="two meshes the reference has: the replace-and-delete check")
    ap.add_argument("--token")
    ap.add_argument("--rounds", type=int, default=12)
    a = ap.parse_args()
    name, path = a.mesh.split("=", 1)
    (old_name, old), (new_name, new) = (s.split("=", 1) for s in a.swap)
    status = upload(a.lb, name, path, a.token)[0]
    if status not in (200, 201):
        sys.exit(f"PUT {name} through the balancer: {status}")
    volume = name + "-sdf"
    job, state = bake(a.lb, name, volume, 40, a.token)
    ref_job, ref_state = bake(a.reference, name, volume, 40, a.token)
    if state["state"] != "done" or ref_state["state"] != "done":
        sys.exit(f"bakes: {state} {ref_state}")
    problems = check_answers(a.lb, a.replica, a.reference, name, volume, job, a.rounds)
    times, more = check_staleness(a.lb, a.replica, a.reference, a.token, (old, old_name),
                                  (new, new_name))
    print(json.dumps({"job": job, **times, "problems": problems + more}))
    return 1 if problems or more else 0


if __name__ == "__main__":
    sys.exit(main())
