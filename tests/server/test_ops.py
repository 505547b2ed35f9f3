"""Field operations through sdfd (POST /v1/volumes/{name}/ops, and "ops" on a bake): the
result's node values against the library's own sdf_volume_apply_ops on the same input
(sdf-volume ops: the same float32 bits), a bake with ops against a bake and then an ops job,
every refused body (422, 404, 401, 405, 413 with the documented byte count), progress and
cancellation, queueing with bakes under --max-bakes, the caveats (grid, topology) and strict
mode, and with --data-dir the result and the job's record across a restart, and a job a
SIGKILL interrupted."""
import http.client
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "clients", "python"))
import sdfclient  # noqa: E402
from harness import DATA, Server, metric, same_bits, wait_until  # noqa: E402

SDF_VOLUME = os.environ.get("SDF_VOLUME", "build/tests/bench/sdf-volume")
TOKEN = "ops-token"
CAVEAT_BITS = {"band": 1, "grid": 2, "topology": 4}
# A long job: SUSSMAN's steps are fixed by "iterations"; a 40^3 step takes about a
# millisecond, so this one runs for many minutes unless canceled.
LONG = {"ops": [{"redistance": 0}], "solver": "sussman", "iterations": 1000000}


def two_boxes_off():
    """Two unit-ish boxes 0.1 apart along x: an outward offset past 0.05 fuses them."""
    verts, faces = [], []
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    for x0, x1 in ((-1.0, -0.05), (0.05, 1.0)):
        base = len(verts)
        verts += [(x, y, z) for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (x0, x1)]
        for a, b, c, d in quads:
            faces += [(base + a, base + b, base + c), (base + a, base + c, base + d)]
    lines = ["OFF", f"{len(verts)} {len(faces)} 0"]
    lines += ["%g %g %g" % v for v in verts] + ["3 %d %d %d" % f for f in faces]
    return ("\n".join(lines) + "\n").encode()


def library_ops(exr, ops, solver="sweep", iterations=0, band=0, strict=False):
    """sdf_volume_apply_ops on the EXR's volume: (values as npy, caveat bits, warning)."""
    args = []
    for op in ops:
        (name, r), = op.items()
        args += ["--op", f"{name}={r!r}"]
    args += ["--solver", solver, "--iterations", str(iterations), "--band", repr(band)]
    args += ["--strict"] if strict else []
    with tempfile.TemporaryDirectory() as d:
        paths = [os.path.join(d, "in.exr"), os.path.join(d, "out.npy")]
        with open(paths[0], "wb") as f:
            f.write(exr)
        out = subprocess.run([SDF_VOLUME, "ops", *paths, "--format", "npy", *args], check=True,
                             capture_output=True, text=True).stdout
        report = json.loads(out)
        return np.load(paths[1]), report["caveats"], report["warning"]


class Ops(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server("--mesh", f"fandisk={os.path.join(DATA, 'fandisk.off')}",
                            "--token", TOKEN, "--max-bakes", "1")
        cls.c = sdfclient.Client(cls.server.url, token=TOKEN)
        cls.c.wait(cls.c.bake("fandisk", volume="fan", resolution=40), timeout=120)
        cls.fan_exr = cls.c.download("fan", "exr")
        cls.c._request("PUT", "/v1/meshes/two", two_boxes_off(),
                       {"Content-Type": "application/octet-stream"})
        cls.c.wait(cls.c.bake("two", volume="two", resolution=[48, 28, 28], margin=0.4))

    @classmethod
    def tearDownClass(cls):
        cls.c.close()
        cls.server.stop()

    def post(self, path, body, token=TOKEN, server=None):
        """(status, headers, JSON) of one POST on a fresh connection."""
        server = server or self.server
        conn = http.client.HTTPConnection("127.0.0.1", server.ports["http"], timeout=60)
        headers = {"Content-Type": "application/json"}
        if token:
            headers["Authorization"] = f"Bearer {token}"
        conn.request("POST", path, json.dumps(body) if not isinstance(body, bytes) else body,
                     headers)
        r = conn.getresponse()
        data = r.read()
        conn.close()
        return r.status, dict(r.getheaders()), json.loads(data) if data else None

    def start_ops(self, source, body, client=None, server=None):
        status, headers, job = self.post(f"/v1/volumes/{source}/ops", body, server=server)
        self.assertEqual(status, 202, job)
        self.assertEqual(headers["Location"], f"/v1/jobs/{job['id']}")
        self.assertEqual(job["href"], headers["Location"])
        self.assertEqual((job["kind"], job["source"]), ("ops", source))
        self.assertEqual(job["volume"], body.get("volume", source))
        return job

    def run_ops(self, source, body):
        job = self.start_ops(source, body)
        return self.c.wait(job, timeout=120)

    def refused(self, path, body, status, code, words, token=TOKEN):
        got, _, answer = self.post(path, body, token=token)
        self.assertEqual(got, status, (body, answer))
        self.assertEqual(answer["error"]["code"], code, answer)
        for w in words:
            self.assertIn(w, answer["error"]["message"], (body, answer))

    # ---- the values: the library's, bit for bit ----

    def test_ops_match_the_library(self):
        cases = [{"ops": [{"round": 0.1}]},
                 {"ops": [{"fillet": 0.05}, {"offset": -0.03}], "solver": "sussman"},
                 {"ops": [{"redistance": 0.15}], "band": 0.05},
                 {"ops": [{"smooth": 0.04}], "iterations": 3},
                 {"ops": [{"offset": -0.05}, {"round": 0.08}], "solver": "sussman",
                  "iterations": 40, "strict": False}]
        for i, body in enumerate(cases):
            with self.subTest(body=body):
                out = f"fan-ops-{i}"
                status = self.run_ops("fan", dict(body, volume=out))
                self.assertEqual((status["progress"], status["percent"]), (1, 100))
                want, bits, warning = library_ops(
                    self.fan_exr, body["ops"], body.get("solver", "sweep"),
                    body.get("iterations", 0), body.get("band", 0))
                got = self.c.download(out, "npy")
                self.assertTrue(same_bits(got, want), f"{out}: values differ from the library's")
                self.assertEqual(sum(CAVEAT_BITS[c] for c in status["caveats"]), bits, status)
                self.assertEqual(status.get("warning", ""), warning)
                meta = self.c.volume(out)
                self.assertEqual((meta["job"], meta["mesh"]), (status["id"], "fandisk"))

    def test_default_output_replaces_the_source(self):
        self.c.upload_volume("self", self.fan_exr)
        job = self.run_ops("self", {"ops": [{"round": 0.1}]})
        self.assertEqual(job["volume"], "self")
        want, _, _ = library_ops(self.fan_exr, [{"round": 0.1}])
        self.assertTrue(same_bits(self.c.download("self", "npy"), want))

    def test_bake_with_ops_is_bake_then_ops(self):
        chain = {"ops": [{"round": 0.1}, {"offset": -0.02}], "solver": "sussman"}
        both = self.c.wait(self.c.bake("fandisk", volume="baked-ops", resolution=40, **chain))
        self.assertEqual((both["kind"], both["caveats"]), ("bake", []))
        self.run_ops("fan", dict(chain, volume="then-ops"))
        self.assertTrue(same_bits(self.c.download("baked-ops", "npy"),
                                  self.c.download("then-ops", "npy")))
        plain = self.c.wait(self.c.bake("fandisk", volume="plain", resolution=12))
        self.assertNotIn("caveats", plain)

    # ---- refusals ----

    def test_refused_bodies(self):
        path = "/v1/volumes/fan/ops"
        bad = [({"ops": []}, ["'ops'", "1..64"]),
               ({"ops": [{"round": 0.1}] * 65}, ["'ops'", "1..64"]),
               ({"ops": {"round": 0.1}}, ["'ops'"]),
               ({}, ["'ops' is required"]),
               ({"ops": [{}]}, ["ops[0]", "exactly one key"]),
               ({"ops": [{"round": 0.1}, {"round": 0.1, "fillet": 0.1}]},
                ["ops[1]", "exactly one key"]),
               ({"ops": [{"bevel": 0.1}]}, ["ops[0]", "unknown operation 'bevel'"]),
               ({"ops": [{"Round": 0.1}]}, ["unknown operation 'Round'"]),
               ({"ops": [{"round": "0.1"}]}, ["ops[0].round", "number"]),
               ({"ops": [{"round": 0.1}], "solver": "fmm"}, ["'solver'"]),
               ({"ops": [{"round": 0.1}], "iterations": 1.5}, ["'iterations'"]),
               ({"ops": [{"round": 0.1}], "iterations": -1}, ["'iterations'"]),
               ({"ops": [{"round": 0.1}], "band": -0.1}, ["'band'"]),
               ({"ops": [{"round": 0.1}], "band": "1"}, ["'band'"]),
               ({"ops": [{"round": 0.1}], "strict": 1}, ["'strict'"]),
               ({"ops": [{"round": 0.1}], "volume": ".x"}, ["'volume'"]),
               ({"ops": [{"round": 0.1}], "resolution": 8}, ["unknown key 'resolution'"])]
        for body, words in bad:
            with self.subTest(body=body):
                self.refused(path, body, 422, "EINVAL", words)
        self.refused(path, b'{"ops": [{"round": 0.1}], "ops": [{"round": 0.2}]}', 422, "EINVAL",
                     ["'ops' is given twice"])
        self.refused(path, b'{"ops": [', 400, "ESYNTAX", [])
        self.refused("/v1/volumes/nothing/ops", {"ops": [{"round": 0.1}]}, 404, "ENOTFOUND",
                     ["nothing"])
        self.refused(path, {"ops": [{"round": 0.1}]}, 401, "EUNAUTHORIZED", [], token=None)
        conn = http.client.HTTPConnection("127.0.0.1", self.server.ports["http"], timeout=30)
        conn.request("GET", path)
        r = conn.getresponse()
        r.read()
        self.assertEqual((r.status, r.getheader("Allow")), (405, "POST"))
        conn.close()

    def test_refused_sources_and_bakes(self):
        self.c.wait(self.c.bake("fandisk", volume="first", resolution=8, order=1))
        self.c.wait(self.c.bake("fandisk", volume="packed", resolution=8, order=1,
                                encoding="packed32"))
        for name, words in (("first", ["zero-order", "order 1 float32"]),
                            ("packed", ["zero-order", "packed32"])):
            self.refused(f"/v1/volumes/{name}/ops", {"ops": [{"round": 0.1}]}, 422, "EINVAL",
                         words)
        bake = "/v1/meshes/fandisk/bake"
        self.refused(bake, {"resolution": 8, "order": 1, "ops": [{"round": 0.1}]}, 422,
                     "EINVAL", ["'ops'", "order 1"])
        self.refused(bake, {"resolution": 8, "solver": "sweep"}, 422, "EINVAL", ["'ops'"])
        self.refused(bake, {"resolution": 8, "ops": [{"smooth": -1}, {"x": 1}]}, 422, "EINVAL",
                     ["ops[1]"])
        # A value only the library judges (r past the grid) fails the job with its message.
        job = self.start_ops("fan", {"ops": [{"round": 50}], "volume": "never"})
        with self.assertRaises(sdfclient.SdfError) as e:
            self.c.wait(job)
        self.assertIn("past the grid", e.exception.message)
        self.assertEqual(self.c.job(job["id"])["error"]["code"], "EINVAL")

    def test_byte_limit(self):
        """An ops job holds its result (4 bytes a node) and the library's scratch (9, +4
        SUSSMAN, +4 when an op offsets) beside the volumes; a bake with ops the larger of its
        bake's working memory and that."""
        nodes = 32 ** 3
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "v.exr")
            subprocess.run([SDF_VOLUME, "bake", os.path.join(DATA, "fandisk.off"), path,
                            "--resolution", "32"], check=True, stdout=subprocess.DEVNULL)
            with open(path, "rb") as f:
                exr = f.read()
        held = 4 * nodes
        with Server("--mesh", f"fandisk={os.path.join(DATA, 'fandisk.off')}",
                    "--max-volume-bytes", str(held + 4 * nodes + 9 * nodes)) as s:
            c = sdfclient.Client(s.url)
            c.upload_volume("v", exr)
            c.wait(self.start_ops("v", {"ops": [{"redistance": 0.1}], "volume": "v"}, server=s))
            for body in ({"ops": [{"round": 0.1}]},
                         {"ops": [{"redistance": 0.1}], "solver": "sussman"}):
                status, _, answer = self.post("/v1/volumes/v/ops", dict(body, volume="w"),
                                              server=s)
                self.assertEqual((status, answer["error"]["code"]), (413, "ELIMIT"), answer)
                self.assertIn(f"need {17 * nodes} bytes ({4 * nodes} for the volume, "
                              f"{13 * nodes} to work in); {held} of", answer["error"]["message"])
            big = 160 ** 3
            needs = {}
            for ops in (None, [{"round": 0.1}], [{"redistance": 0.1}]):
                body = {"resolution": 160, "volume": "w"}
                if ops:
                    body.update(ops=ops, solver="sussman")
                status, _, answer = self.post("/v1/meshes/fandisk/bake", body, server=s)
                self.assertEqual(status, 413, answer)
                m = re.search(r"needs (\d+) bytes \((\d+) for the volume, (\d+) to work in\)",
                              answer["error"]["message"])
                needs[str(ops)] = tuple(int(g) for g in m.groups())
            bake = needs["None"]
            self.assertEqual(bake[1], 4 * big)
            for ops, per_node in (([{"round": 0.1}], 21), ([{"redistance": 0.1}], 17)):
                working = max(bake[2], per_node * big)
                self.assertEqual(needs[str(ops)], (4 * big + working, 4 * big, working))
            self.assertGreater(21 * big, bake[2])  # else the round case proves nothing
            c.close()

    def test_deleted_source_stays_counted(self):
        """A source deleted (or evicted) while an ops job reads it is still in memory: its
        bytes count against --max-volume-bytes until the job ends."""
        held = re.compile(r"(\d+) of --max-volume-bytes \d+ are held or promised")

        def held_bytes(s):
            status, _, answer = self.post("/v1/meshes/fandisk/bake",
                                          {"resolution": 400, "volume": "big"}, server=s)
            self.assertEqual(status, 413, answer)
            return int(held.search(answer["error"]["message"]).group(1))

        with Server("--mesh", f"fandisk={os.path.join(DATA, 'fandisk.off')}", "--token", TOKEN,
                    "--max-volume-bytes", str(64 << 20)) as s:
            c = sdfclient.Client(s.url, token=TOKEN)
            c.upload_volume("v", self.fan_exr)
            job = self.start_ops("v", dict(LONG, volume="out"), server=s)
            self.assertTrue(wait_until(lambda: c.job(job["id"])["state"] == "running", 60))
            before = held_bytes(s)
            self.assertGreater(before, 4 * 40 ** 3)  # the source and the job's promise
            c._request("DELETE", "/v1/volumes/v")
            self.assertNotIn("v", [v["name"] for v in c.volumes()])
            self.assertEqual(held_bytes(s), before)
            c.cancel(job["id"])
            self.assertTrue(wait_until(lambda: c.job(job["id"])["state"] == "canceled", 30))
            self.assertEqual(held_bytes(s), 0)
            c.close()

    # ---- jobs: progress, cancellation, queueing with bakes ----

    def test_cancel_and_queue(self):
        running = self.start_ops("fan", dict(LONG, volume="long"))
        self.assertTrue(wait_until(lambda: 0 < self.c.job(running["id"])["progress"] < 1, 60))
        queued = self.start_ops("fan", dict(LONG, volume="long2"))
        bake = self.c.bake("fandisk", volume="waits", resolution=8)
        self.assertEqual(self.c.job(queued["id"])["state"], "queued")
        self.assertEqual(self.c.job(bake["id"])["state"], "queued")  # one job at a time
        text = self.c._request("GET", "/metrics")[1].decode()
        self.assertEqual(metric(text, "sdfd_ops_jobs", 'state="running"'), 1)
        self.assertEqual(metric(text, "sdfd_ops_jobs", 'state="queued"'), 1)
        self.assertEqual(metric(text, "sdfd_bakes", 'state="queued"'), 1)
        for job in (queued, running):
            self.assertTrue(self.c.cancel(job["id"])["cancel_requested"])
        for job in (queued, running):
            self.assertTrue(wait_until(lambda: self.c.job(job["id"])["state"] == "canceled", 30))
        self.assertEqual(self.c.wait(bake)["state"], "done")
        names = [v["name"] for v in self.c.volumes()]
        self.assertNotIn("long", names)
        self.assertNotIn("long2", names)

    # ---- caveats ----

    def test_caveats_and_strict(self):
        two_exr = self.c.download("two", "exr")
        for r, caveat in ((0.1, "topology"), (0.35, "grid")):
            with self.subTest(r=r):
                body = {"ops": [{"offset": r}], "volume": "two-off"}
                job = self.run_ops("two", body)
                self.assertIn(caveat, job["caveats"])
                want, bits, warning = library_ops(two_exr, body["ops"])
                self.assertEqual(sum(CAVEAT_BITS[c] for c in job["caveats"]), bits)
                self.assertEqual(job["warning"], warning)
                self.assertTrue(same_bits(self.c.download("two-off", "npy"), want))
                strict = self.start_ops("two", dict(body, volume="two-strict", strict=True))
                with self.assertRaises(sdfclient.SdfError) as e:
                    self.c.wait(strict)
                self.assertEqual((e.exception.code, e.exception.message), ("EINVAL", warning))
                self.assertNotIn("two-strict", [v["name"] for v in self.c.volumes()])
        job = self.run_ops("two", {"ops": [{"offset": -0.1}], "volume": "two-in"})
        self.assertEqual(job["caveats"], [])
        self.assertNotIn("warning", job)


class Persistence(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="sdfd-ops-")
        self.servers = []

    def tearDown(self):
        for s in self.servers:
            s.stop()
        shutil.rmtree(self.dir, ignore_errors=True)

    def start(self):
        s = Server("--data-dir", self.dir, "--mesh", f"fandisk={os.path.join(DATA, 'fandisk.off')}")
        self.servers.append(s)
        return s, sdfclient.Client(s.url)

    def test_result_and_record_survive_a_restart(self):
        s, c = self.start()
        c.wait(c.bake("fandisk", volume="fan", resolution=24))
        exr = c.download("fan", "exr")
        ops = [{"offset": 0.25}]
        r = c._request("POST", "/v1/volumes/fan/ops", json.dumps({"ops": ops, "volume": "out"}))
        done = c.wait(json.loads(r[1]))
        want, bits, warning = library_ops(exr, ops)
        self.assertTrue(bits)  # the record must carry a caveat and its warning
        self.assertEqual(sum(CAVEAT_BITS[k] for k in done["caveats"]), bits)
        c.close()
        s.stop()
        s, c = self.start()
        self.assertTrue(same_bits(c.download("out", "npy"), want))
        record = c.job(done["id"])
        keys = ("kind", "source", "volume", "state", "caveats", "warning")
        self.assertEqual({k: record[k] for k in keys}, {k: done[k] for k in keys})
        self.assertEqual(done["warning"], warning)
        job = json.loads(c._request("POST", "/v1/volumes/fan/ops",
                                    json.dumps(dict(LONG, volume="slow")))[1])
        self.assertTrue(wait_until(lambda: c.job(job["id"])["state"] == "running", 30))
        c.close()
        s.stop(sig=signal.SIGKILL)
        s, c = self.start()
        status = c.job(job["id"])
        self.assertEqual((status["state"], status["kind"], status["source"]),
                         ("failed", "ops", "fan"))
        self.assertIn("interrupted", status["error"]["message"])
        with self.assertRaises(sdfclient.SdfError):
            c.volume("slow")
        c.close()


if __name__ == "__main__":
    unittest.main(verbosity=2)
