"""sdfd's HTTP API and binary protocol against the library itself: the same points, queried
in-process by sdf-bench (which calls sdf_query directly) and through every body form and
the binary protocol, must give the same float32 bits. Plus mesh management, auth, and the
documented error statuses."""
import http.client
import io
import json
import os
import select
import socket
import subprocess
import sys
import tempfile
import threading
import unittest
import urllib.request

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "clients", "python"))
import sdfclient  # noqa: E402
import harness  # noqa: E402
from harness import DATA, SDF_BENCH, Server, same_bits, wait_until  # noqa: E402


def library_results(mesh, points, mode, sign="auto", samples=None, sample_gradient=False):
    """sdf-bench --out: (N,) or (N, 4) float32 straight from sdf_query (or, for the filtered
    modes, sdf_query_filtered with `samples`, the default seed and `sample_gradient`)."""
    with tempfile.TemporaryDirectory() as d:
        np.save(os.path.join(d, "p.npy"), points)
        out = os.path.join(d, "out.npy")
        extra = ["--samples", str(samples)] if samples else []
        extra += ["--sample-gradient", "1"] if sample_gradient else []
        subprocess.run([SDF_BENCH, mesh, os.path.join(d, "p.npy"), "--mode", mode, "--sign", sign,
                        "--repeat", "1", "--out", out] + extra, check=True,
                       stdout=subprocess.DEVNULL)
        return np.load(out)


class Exactness(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.mesh = os.path.join(DATA, "fandisk.off")
        cls.server = Server("--mesh", f"fandisk={cls.mesh}")
        cls.http = sdfclient.Client(cls.server.url)
        cls.bin = sdfclient.BinaryClient("127.0.0.1", cls.server.bin_port)
        rng = np.random.default_rng(5)
        cls.points = rng.uniform(-0.2, 0.2, (3000, 3)).astype(np.float32)

    @classmethod
    def tearDownClass(cls):
        cls.http.close()
        cls.bin.close()
        cls.server.stop()

    def check_mode(self, mode, sign="auto", samples=None):
        ref = library_results(self.mesh, self.points, mode, sign, samples)
        ref_d = ref if ref.ndim == 1 else ref[:, 0]
        f = {"samples": samples} if samples else None
        answers = {form: self.http.query("fandisk", self.points, mode=mode, sign=sign, form=form,
                                         filter=f)
                   for form in ("json", "octet", "npy")}
        answers["binary"] = self.bin.query("fandisk", self.points, mode=mode, sign=sign, filter=f)
        for form, r in answers.items():
            self.assertTrue(same_bits(r["distance"], ref_d), f"{mode}/{sign} {form}: distance")
            if mode in ("gradient", "filtered-gradient"):
                self.assertTrue(same_bits(r["gradient"], ref[:, 1:4]), f"{form}: gradient")
            if mode == "closest":
                self.assertTrue(same_bits(r["closest"], ref[:, 1:4]), f"{form}: closest")
                self.assertTrue(np.array_equal(r["triangle"], answers["binary"]["triangle"]))

    def test_batch_scratch_metric(self):
        """/metrics tells what the batcher keeps between batches: a batch's gathered points and
        answers (32 bytes a point) and the library's workspace (the Morton order and keys, the
        visit-order copies: 36 more for distances alone)."""
        p = np.random.default_rng(8).uniform(-0.2, 0.2, (100000, 3)).astype(np.float32)
        self.bin.query("fandisk", p)
        kept = harness.metric(self.http.metrics(), "sdfd_batch_scratch_bytes")
        self.assertGreaterEqual(kept, 60 * len(p))

    def test_value_names_in_any_case(self):
        """A value's name (mode, sign, axis, format, kernel) is accepted in any case, and the
        answer is the lowercase name's; a member's name is not (docs/api.md)."""
        def raw(method, path, body=None):
            conn = http.client.HTTPConnection("127.0.0.1", self.server.ports["http"], timeout=30)
            headers = {"Content-Type": "application/json"} if body is not None else {}
            conn.request(method, path, json.dumps(body) if body is not None else None, headers)
            r = conn.getresponse()
            out = (r.status, r.read())
            conn.close()
            return out
        pts = self.points[:50].tolist()
        for upper, lower in (({"mode": "GRADIENT", "sign": "Winding"},
                              {"mode": "gradient", "sign": "winding"}),
                             ({"mode": "Filtered", "filter": {"kernel": "BUMP"}},
                              {"mode": "filtered", "filter": {"kernel": "bump"}})):
            a = raw("POST", "/v1/meshes/fandisk/query", dict(upper, points=pts))
            b = raw("POST", "/v1/meshes/fandisk/query", dict(lower, points=pts))
            self.assertEqual(a, b)
            self.assertEqual(a[0], 200, a)
        a = raw("GET", "/v1/meshes/fandisk/slice.png?axis=Y&mode=DISTANCE&format=Npy&size=16")
        b = raw("GET", "/v1/meshes/fandisk/slice.png?axis=y&mode=distance&format=npy&size=16")
        self.assertEqual(a, b)
        self.assertEqual(a[0], 200)
        status, body = raw("POST", "/v1/meshes/fandisk/query", {"Points": pts})
        self.assertEqual(status, 422, body)

    def test_signed(self):
        self.check_mode("signed")

    def test_signed_winding(self):
        self.check_mode("signed", "winding")

    def test_signed_raycast(self):
        """Rays need Embree's scene, which a mesh commits on its first raycast query."""
        self.check_mode("signed", "raycast")

    def test_distance(self):
        self.check_mode("distance")

    def test_gradient(self):
        self.check_mode("gradient")

    def test_closest(self):
        self.check_mode("closest")

    def test_filtered(self):
        self.check_mode("filtered", samples=16)

    def test_filtered_gradient(self):
        self.check_mode("filtered-gradient", samples=8)

    def test_sample_gradient(self):
        """sample_gradient travels in every form: the library's floats for it, g's value
        unchanged, and a gradient that is not g's own near the surface."""
        p = self.points[:800]
        ref = library_results(self.mesh, p, "filtered-gradient", samples=8, sample_gradient=True)
        f = {"samples": 8, "sample_gradient": True}
        answers = {form: self.http.query("fandisk", p, mode="filtered-gradient", form=form,
                                         filter=f)
                   for form in ("json", "octet", "npy")}
        answers["binary"] = self.bin.query("fandisk", p, mode="filtered-gradient", filter=f)
        analytic = self.bin.query("fandisk", p, mode="filtered-gradient", filter={"samples": 8})
        for form, r in answers.items():
            self.assertTrue(same_bits(r["distance"], ref[:, 0]), f"{form}: distance")
            self.assertTrue(same_bits(r["gradient"], ref[:, 1:4]), f"{form}: gradient")
            self.assertTrue(same_bits(r["distance"], analytic["distance"]), f"{form}: g")
            self.assertFalse(same_bits(r["gradient"], analytic["gradient"]), form)

    def test_localized_smoothing(self):
        """A smoothing sphere travels in every form: outside it the answer is the raw signed
        distance bit for bit, inside it differs; a box given as a loaded mesh matches the
        same box given by its corners."""
        p = self.points
        centre, radius = [0.0, 0.0, 0.0], 0.15
        f = {"samples": 8, "smooth": {"sphere": centre + [radius], "depth": 0.05}}
        answers = [self.http.query("fandisk", p, mode="filtered", form=form, filter=f)["distance"]
                   for form in ("json", "octet", "npy")]
        answers.append(self.bin.query("fandisk", p, mode="filtered", filter=f)["distance"])
        for a in answers[1:]:
            self.assertTrue(same_bits(a, answers[0]))
        raw = self.http.query("fandisk", p, mode="signed")["distance"]
        outside = np.linalg.norm(p - np.array(centre, np.float32), axis=1) > radius * 1.0001
        self.assertTrue(outside.sum() > 100 and (~outside).sum() > 100)
        self.assertTrue(same_bits(answers[0][outside], raw[outside]))
        self.assertFalse(same_bits(answers[0][~outside], raw[~outside]))
        # The same box, by corners and as a loaded mesh volume.
        lo, hi = np.array([-0.1, -0.12, -0.08]), np.array([0.11, 0.1, 0.12])
        corners = np.array([[hi[k] if i >> k & 1 else lo[k] for k in range(3)] for i in range(8)])
        tris = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
                (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]
        with tempfile.NamedTemporaryFile("w", suffix=".off", delete=False) as off:
            off.write(f"OFF\n8 12 0\n" + "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in corners)
                      + "".join(f"3 {a} {b} {c}\n" for a, b, c in tris))
        try:
            self.http.upload("smoothbox", off.name)
        finally:
            os.unlink(off.name)
        by_box = self.bin.query("fandisk", p, mode="filtered",
                                filter={"samples": 8, "smooth": {"box": list(lo) + list(hi)}})
        by_mesh = self.bin.query("fandisk", p, mode="filtered",
                                 filter={"samples": 8, "smooth": {"mesh": "smoothbox"}})
        by_mesh_url = self.http.query("fandisk", p, mode="filtered", form="octet",
                                      filter={"samples": 8, "smooth": {"mesh": "smoothbox"}})
        self.assertTrue(same_bits(by_mesh["distance"], by_mesh_url["distance"]))
        self.assertLess(np.abs(by_box["distance"] - by_mesh["distance"]).max(), 1e-4)
        self.http.delete("smoothbox")

    def test_pipelined_filters_are_not_mixed(self):
        """Filtered requests that differ in any parameter (here only the smoothing volume, or
        only adaptivity) are never run as one batch: pipelined together, each gets the answer
        it gets alone."""
        p = self.points[:400]
        filters = [{"samples": 8}, {"samples": 8, "smooth": {"sphere": [0, 0, 0, 0.1]}},
                   {"samples": 8, "smooth": {"sphere": [0, 0, 0, 0.2]}},
                   {"samples": 8, "min_samples": 2}, {"samples": 8, "seed": 1}]
        alone = [self.bin.query("fandisk", p, mode="filtered", filter=f)["distance"]
                 for f in filters]
        for rounds in range(3):
            ids = [self.bin._send(0x03, self.bin._query_payload("fandisk", p, "filtered", "auto", f))
                   for f in filters]
            got = {}
            while len(got) < len(ids):
                rid, _, payload = self.bin._recv()
                got[rid] = self.bin._result(payload, "filtered")["distance"]
            for i, rid in enumerate(ids):
                self.assertTrue(same_bits(got[rid], alone[i]), f"filter {filters[i]}")

    def test_filtered_parameters_reach_the_library(self):
        """Every filter parameter travels in all forms: the same non-default request gives
        the same floats over JSON, octet-stream, npy and the binary protocol, and they differ
        from the defaults."""
        f = {"kernel": "bump", "cap": 0.05, "b": 0.04, "samples": 12, "unsigned": True,
             "seed": 99, "grid": False, "allow_wide_bump": False, "min_samples": 4,
             "medial": 0.3}
        p = self.points[:500]
        answers = [self.http.query("fandisk", p, mode="filtered", form=form, filter=f)["distance"]
                   for form in ("json", "octet", "npy")]
        answers.append(self.bin.query("fandisk", p, mode="filtered", filter=f)["distance"])
        for a in answers[1:]:
            self.assertTrue(same_bits(a, answers[0]))
        default = self.http.query("fandisk", p, mode="filtered", filter={"samples": 12})
        self.assertFalse(same_bits(default["distance"], answers[0]))

    def test_accept_overrides_form(self):
        body = json.dumps({"points": self.points[:10].tolist()}).encode()
        req = urllib.request.Request(f"{self.server.url}/v1/meshes/fandisk/query", body, method="POST",
                                     headers={"Content-Type": "application/json",
                                              "Accept": "application/x-npy"})
        with urllib.request.urlopen(req) as resp:
            self.assertEqual(resp.headers["Content-Type"], "application/x-npy")
            self.assertEqual(resp.headers["X-SDF-Count"], "10")
            a = np.load(io.BytesIO(resp.read()))
        self.assertTrue(same_bits(a, library_results(self.mesh, self.points[:10], "signed")))

    def test_float64_npy(self):
        buf = io.BytesIO()
        np.save(buf, self.points.astype(np.float64))
        req = urllib.request.Request(f"{self.server.url}/v1/meshes/fandisk/query", buf.getvalue(),
                                     method="POST", headers={"Content-Type": "application/x-npy"})
        with urllib.request.urlopen(req) as resp:
            a = np.load(io.BytesIO(resp.read()))
        self.assertTrue(same_bits(a, library_results(self.mesh, self.points, "signed")))


class Meshes(unittest.TestCase):
    def test_upload_replace_delete_and_auth(self):
        with Server("--token", "s3cret") as s:
            anon = sdfclient.Client(s.url)
            admin = sdfclient.Client(s.url, token="s3cret")
            self.addCleanup(anon.close)
            self.addCleanup(admin.close)
            with self.assertRaises(sdfclient.SdfError) as e:
                anon.upload("knot", os.path.join(DATA, "knot1.off"))
            self.assertEqual((e.exception.status, e.exception.code), (401, "EUNAUTHORIZED"))
            rep = admin.upload("knot", os.path.join(DATA, "knot1.off"))
            self.assertEqual((rep["triangles"], rep["closed"], rep["sign"]), (6400, True, "pseudonormal"))
            self.assertEqual((rep["warnings"], "warning" in rep), (0, False))
            with tempfile.NamedTemporaryFile(suffix=".ply") as f:  # Blender 2.4x's header
                f.write(b"ply\nformat ascii 1.0\nCreated by Blender3D 247\nelement vertex 3\n"
                        b"property float x\nproperty float y\nproperty float z\nelement face 1\n"
                        b"property list uchar uint vertex_indices\nend_header\n"
                        b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
                f.flush()
                rep = admin.upload("blender", f.name)
            self.assertEqual((rep["triangles"], rep["warnings"]), (1, 1))
            self.assertIn("PLY line 3: unknown header keyword 'Created'", rep["warning"])
            conn = http.client.HTTPConnection("127.0.0.1", s.ports["http"], timeout=30)
            conn.request("DELETE", "/v1/meshes/blender", headers={"Authorization": "Bearer s3cret"})
            r = conn.getresponse()
            self.assertEqual((r.status, r.read(), r.getheader("Content-Type")), (204, b"", None),
                             "a 204 has no body, so no Content-Type")
            conn.close()
            names = sorted(m["name"] for m in anon.meshes())
            self.assertEqual(names, ["demo", "knot"])
            p = np.zeros((1, 3), np.float32)
            before = anon.query("knot", p)["distance"]
            # A replace while a big query is in flight: the query finishes on the old mesh.
            big = np.random.default_rng(2).uniform(-0.3, 0.3, (300000, 3)).astype(np.float32)
            expected = library_results(os.path.join(DATA, "knot1.off"), big, "signed")
            got = {}
            t = threading.Thread(target=lambda: got.update(
                r=sdfclient.BinaryClient("127.0.0.1", s.bin_port).query("knot", big)))
            t.start()
            self.assertTrue(wait_until(lambda: (harness.metric(anon.metrics(), "sdfd_points_total")
                                                or 0) >= 300000, 30))
            rep = admin.upload("knot", os.path.join(DATA, "fandisk.off"))  # atomic replace
            self.assertEqual(rep["triangles"], 12946)
            t.join(60)
            self.assertTrue(same_bits(got["r"]["distance"], expected), "in-flight query changed mesh")
            self.assertNotEqual(anon.query("knot", p)["distance"][0], before[0])
            self.assertEqual(anon.mesh("knot")["triangles"], 12946)
            with self.assertRaises(sdfclient.SdfError) as e:
                admin.upload("bad", os.path.join(DATA, "issue623.ply"))
            self.assertEqual(e.exception.status, 422)
            self.assertIn("face element", e.exception.message)
            with self.assertRaises(sdfclient.SdfError) as e:
                admin.upload("knot", os.path.join(DATA, "knot1.off"), format="3ds")
            self.assertEqual(e.exception.status, 415)
            admin.delete("knot")
            with self.assertRaises(sdfclient.SdfError) as e:
                anon.query("knot", p)
            self.assertEqual(e.exception.status, 404)
            with self.assertRaises(sdfclient.SdfError) as e:
                admin.delete("knot")
            self.assertEqual(e.exception.status, 404)

    def test_queries_need_token_when_asked(self):
        with Server("--token", "t", "--auth-queries") as s:
            with self.assertRaises(sdfclient.SdfError) as e:
                sdfclient.Client(s.url).query("demo", np.zeros((1, 3)))
            self.assertEqual(e.exception.status, 401)
            admin = sdfclient.Client(s.url, token="t")
            admin.query("demo", np.zeros((1, 3)))
            # A volume download is every node's answer: it needs the token too.
            admin.wait(admin.bake("demo", volume="v", resolution=4), timeout=60)
            with self.assertRaises(sdfclient.SdfError) as e:
                sdfclient.Client(s.url).download("v", "raw")
            self.assertEqual(e.exception.status, 401)
            self.assertEqual(len(admin.download("v", "raw")), 4 * 4 ** 3)
            # The binary protocol too: queries wait for AUTH; the mesh list does not.
            b = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            self.assertEqual([m["name"] for m in b.meshes()], ["demo"])
            for call in (lambda: b.query("demo", np.zeros((1, 3))),
                         lambda: b.query_volume("v", np.zeros((1, 3)))):
                with self.assertRaises(sdfclient.SdfError) as e:
                    call()
                self.assertEqual((e.exception.status, e.exception.code), (401, "EUNAUTHORIZED"))
            with self.assertRaises(sdfclient.SdfError) as e:
                b.auth("wrong")
            self.assertEqual(e.exception.status, 401)
            with self.assertRaises((ConnectionError, OSError)):  # a wrong token closes it
                b.meshes()
            b.close()
            b = sdfclient.BinaryClient("127.0.0.1", s.bin_port, token="t")
            self.assertEqual(len(b.query("demo", np.zeros((2, 3)))["distance"]), 2)
            b.close()
        with Server("--token", "t") as s:  # queries are open; AUTH is accepted all the same
            b = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            self.assertEqual(len(b.query("demo", np.zeros((1, 3)))["distance"]), 1)
            b.auth("t")
            b.close()

    def test_mesh_dir_and_flags(self):
        with tempfile.TemporaryDirectory() as d:
            for f in ("knot1.off", "cube.ply"):
                with open(os.path.join(DATA, f), "rb") as src, open(os.path.join(d, f), "wb") as dst:
                    dst.write(src.read())
            with Server("--mesh-dir", d) as s:
                names = sorted(m["name"] for m in sdfclient.Client(s.url).meshes())
                self.assertEqual(names, ["cube", "knot1"])
            # Two files of one stem would leave whichever the directory lists last: refused.
            with open(os.path.join(DATA, "knot1.off"), "rb") as src, \
                    open(os.path.join(d, "cube.off"), "wb") as dst:
                dst.write(src.read())
            r = subprocess.run([os.environ.get("SDFD", "build/server/sdfd"), "--mesh-dir", d,
                                "--http", "127.0.0.1:0", "--bin", "127.0.0.1:0"],
                               capture_output=True, timeout=30)
            self.assertNotEqual(r.returncode, 0)
            self.assertIn(b"two meshes are named 'cube'", r.stderr)
        r = subprocess.run([os.environ.get("SDFD", "build/server/sdfd"), "--mesh",
                            f"k={os.path.join(DATA, 'knot1.off')}", "--mesh",
                            f"k={os.path.join(DATA, 'cube.ply')}", "--http", "127.0.0.1:0",
                            "--bin", "127.0.0.1:0"], capture_output=True, timeout=30)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn(b"two meshes are named 'k'", r.stderr)
        env = dict(os.environ, SDFD_TOKEN="")  # an unset variable's expansion, say
        r = subprocess.run([os.environ.get("SDFD", "build/server/sdfd"), "--http", "127.0.0.1:0",
                            "--bin", "127.0.0.1:0"], env=env, capture_output=True, timeout=30)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn(b"SDFD_TOKEN: the value is empty", r.stderr)
        env = dict(os.environ, SDFD_THREADS="many")
        r = subprocess.run([os.environ.get("SDFD", "build/server/sdfd")], env=env,
                           capture_output=True, timeout=30)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn(b"SDFD_THREADS", r.stderr)
        r = subprocess.run([os.environ.get("SDFD", "build/server/sdfd"), "--mesh", "x=/nonexistent.obj",
                            "--http", "127.0.0.1:0", "--bin", "127.0.0.1:0"], capture_output=True, timeout=30)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn(b"nonexistent", r.stderr)
        # Out-of-range values are refused with the range; a port past 65535 is not wrapped
        # round to another one.
        for args, says in [(["--timeout", "0"], b"'0' is not a whole number in 1..86400"),
                           (["--max-jobs", "0"], b"in 1..65536"),
                           (["--http", "127.0.0.1:70000"], b"PORT 0..65535"),
                           # an empty token would be one anybody can send
                           (["--token", ""], b"--token: the value is empty"),
                           # a budget smaller than one request would have it retry for ever
                           (["--max-buffered-bytes", "1000"], b"cannot hold the largest request")]:
            r = subprocess.run([os.environ.get("SDFD", "build/server/sdfd"), "--bin", "127.0.0.1:0",
                                *args], capture_output=True, timeout=30)
            self.assertNotEqual(r.returncode, 0, args)
            self.assertIn(says, r.stderr, args)
        r = subprocess.run([os.environ.get("SDFD", "build/server/sdfd"), "--help"], capture_output=True)
        self.assertEqual(r.returncode, 0)
        self.assertIn(b"--batch-window-us", r.stdout)
        self.assertIn(b"--version", r.stdout)
        # meson.build's project version, handed over by the test's environment
        r = subprocess.run([os.environ.get("SDFD", "build/server/sdfd"), "--version"],
                           capture_output=True, timeout=30)
        self.assertEqual(r.returncode, 0)
        self.assertEqual(r.stdout.decode(), "sdfd %s\n" % os.environ["SDF_VERSION"])


def read_off(path):
    """(vertices float32 (V, 3), faces int64 (F, 3)) of a triangle OFF file."""
    with open(path) as f:
        words = f.read().split()
    assert words[0] == "OFF"
    nv, nf = int(words[1]), int(words[2])
    at = 4
    v = np.array(words[at:at + 3 * nv], np.float32).reshape(nv, 3)
    at += 3 * nv
    rows = np.array(words[at:at + 4 * nf], np.int64).reshape(nf, 4)
    assert (rows[:, 0] == 3).all()
    return v, rows[:, 1:]


def put(port, name, body, content_type, query=""):
    """(status, parsed JSON) of PUT /v1/meshes/{name}."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    try:
        conn.request("PUT", "/v1/meshes/%s%s" % (name, query), body,
                     {"Content-Type": content_type})
        r = conn.getresponse()
        body = json.loads(r.read())
        return r.status, body.get("error", body)
    finally:
        conn.close()


def npz_bytes(compressed=False, **arrays):
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, **arrays)
    return buf.getvalue()


class MeshArrays(unittest.TestCase):
    """PUT /v1/meshes/{name} with {"vertices", "faces"} JSON or an npz: the same mesh as the
    file, answering the same bits; malformed arrays are refused, naming what is wrong."""

    def test_same_mesh_as_the_file(self):
        v, f = read_off(os.path.join(DATA, "fandisk.off"))
        points = np.random.default_rng(5).uniform(-0.6, 0.6, (2000, 3)).astype(np.float32)
        with Server() as s:
            c = sdfclient.Client(s.url)
            self.addCleanup(c.close)
            c.upload("file", os.path.join(DATA, "fandisk.off"))
            want = c.query("file", points)["distance"]
            bodies = {
                "json": (json.dumps({"vertices": v.tolist(), "faces": f.tolist()}),
                         "application/json"),
                "npz": (npz_bytes(vertices=v, faces=f), "application/octet-stream"),
                "npz_compressed": (npz_bytes(True, vertices=v, faces=f.astype(np.int32)),
                                   "application/x-npz"),
                "npz_f64_u16": (npz_bytes(vertices=v.astype(np.float64),
                                          faces=f.astype(np.uint16)), "application/octet-stream"),
            }
            for name, (body, ctype) in bodies.items():
                status, rep = put(s.ports["http"], name, body, ctype)
                self.assertEqual((status, rep["triangles"], rep["closed"]), (201, 12946, True),
                                 (name, rep))
                self.assertTrue(same_bits(c.query(name, points)["distance"], want), name)
            rep = c.upload_arrays("client", v, f)  # the Python client sends an npz
            self.assertEqual((rep["triangles"], rep["format"]), (12946, "ply"))
            self.assertTrue(same_bits(c.query("client", points)["distance"], want))
            with self.assertRaises(ValueError):
                c.upload_arrays("client", v, f.astype(np.float32))
            with self.assertRaises(ValueError):
                c.upload_arrays("client", v[:, :2], f)

    def test_malformed_arrays(self):
        tri = {"vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]]}
        v = np.array(tri["vertices"], np.float32)
        cases = [
            ({"vertices": tri["vertices"], "faces": [[0, 1, 3]]}, 422, "faces[0][2] = 3 is out of range"),
            ({"vertices": [[0, 0, 0], [1, 0], [0, 1, 0]], "faces": [[0, 1, 2]]}, 422,
             "vertices[1] has 2 numbers, not 3"),
            ({"vertices": tri["vertices"], "faces": [[0, 1, 2, 0]]}, 422, "faces[0] has 4 numbers"),
            ({"vertices": tri["vertices"], "faces": [[0, 1.5, 2]]}, 422, "faces[0][1] = 1.5 is not an integer"),
            ({"vertices": tri["vertices"], "faces": [[0, -1, 2]]}, 422, "faces[0][1] = -1 is out of range"),
            ({"vertices": tri["vertices"]}, 422, '"faces" is missing'),
            ({"vertices": tri["vertices"], "faces": []}, 422, "the mesh has no faces"),
            ({"vertices": tri["vertices"], "faces": [[0, 1, 2]], "normals": []}, 422, 'unknown key "normals"'),
            ({"vertices": [[0, 0, 1e39], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]]}, 422,
             "is not a finite float32"),
        ]
        with Server() as s:
            port = s.ports["http"]
            for body, status, message in cases:
                got, err = put(port, "bad", json.dumps(body), "application/json")
                self.assertEqual(got, status, (body, err))
                self.assertIn(message, err["message"], body)
            got, err = put(port, "bad", '{"vertices": [[NaN, 0, 0], [1, 0, 0], [0, 1, 0]], '
                           '"faces": [[0, 1, 2]]}', "application/json")
            self.assertEqual((got, err["code"]), (422, "EINVAL"), err)
            self.assertIn("vertices[0][0] is not a number", err["message"])
            got, err = put(port, "bad", '{"vertices": [[0, 0, 0]', "application/json")
            self.assertEqual((got, err["code"]), (400, "ESYNTAX"), err)
            npz_cases = [
                (npz_bytes(vertices=np.array([[np.nan, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32),
                           faces=np.array([[0, 1, 2]])), 422, "vertices[0][0] = nan is not a finite"),
                (npz_bytes(vertices=v, faces=np.array([[0, 1, 7]], np.int8)), 422,
                 "faces[0][2] = 7 is out of range: there are 3 vertices"),
                (npz_bytes(vertices=v, faces=np.array([[0, 1, -2]], np.int64)), 422,
                 "faces[0][2] = -2 is out of range"),
                (npz_bytes(vertices=v, faces=np.array([[0.0, 1, 2]])), 422, "'faces' must hold integers"),
                (npz_bytes(vertices=v, faces=np.array([0, 1, 2])), 422, "'faces' must have shape (N, 3)"),
                (npz_bytes(vertices=v), 422, "no member 'faces'"),
                (npz_bytes(vertices=v.astype(">f4"), faces=np.array([[0, 1, 2]])), 415,
                 "npy dtype must be"),
                (npz_bytes(True, vertices=v, faces=np.array([[0, 1, 2]]))[:-30], 415,
                 "no end of central directory"),
            ]
            for body, status, message in npz_cases:
                got, err = put(port, "bad", body, "application/octet-stream")
                self.assertEqual(got, status, (message, err))
                self.assertIn(message, err["message"])
            # format=auto sniffs arrays too.
            got, rep = put(port, "auto", json.dumps(tri), "application/json", "?format=auto")
            self.assertEqual((got, rep["triangles"]), (201, 1), rep)
            request_delete = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
            request_delete.request("DELETE", "/v1/meshes/auto")
            self.assertEqual(request_delete.getresponse().status, 204)
            request_delete.close()
            # A small npz that would inflate past 32 times its size is refused before inflating.
            bomb = npz_bytes(True, vertices=v, faces=np.zeros((2000000, 3), np.int64))
            self.assertLess(len(bomb), 48000000 // 32)
            got, err = put(port, "bad", bomb, "application/octet-stream")
            self.assertEqual((got, err["code"]), (413, "ELIMIT"), err)
            self.assertIn("more than the server reads", err["message"])
            # A damaged deflated member: its CRC-32 or its inflation says so.
            good = bytearray(npz_bytes(True, vertices=v, faces=np.array([[0, 1, 2]] * 50)))
            at = bytes(good).index(b"faces.npy") + len("faces.npy") + 20 + 8  # in its data
            good[at] ^= 0x55
            got, err = put(port, "bad", bytes(good), "application/octet-stream")
            self.assertEqual(got, 415, err)
            self.assertRegex(err["message"], "CRC-32|inflate|local header")
            self.assertEqual(c_names(port), ["demo"], "nothing half-stored")


def post_npy(port, path, array):
    """(status, the npy answer as an array, or the error) of an npy POST answered in npy."""
    buf = io.BytesIO()
    np.save(buf, array)
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    try:
        conn.request("POST", path, buf.getvalue(), {"Content-Type": "application/x-npy",
                                                   "Accept": "application/x-npy"})
        r = conn.getresponse()
        body = r.read()
        if r.status != 200:
            return r.status, json.loads(body)["error"]
        return r.status, np.load(io.BytesIO(body))
    finally:
        conn.close()


class LeadingShape(unittest.TestCase):
    """npy points of shape (..., 3): answers in npy keep the leading shape, with the same
    values as the same points sent as (N, 3)."""

    def test_shapes_kept(self):
        rng = np.random.default_rng(8)
        with Server() as s:
            c = sdfclient.Client(s.url)
            self.addCleanup(c.close)
            c.upload("fan", os.path.join(DATA, "fandisk.off"))
            vol = c.wait(c.bake("fan", resolution=16, volume="fan16"), timeout=60)
            self.assertEqual(vol["state"], "done")
            port = s.ports["http"]
            for lead in [(4, 5), (2, 3, 4), (1, 1), (7, 1)]:
                p = rng.uniform(-0.6, 0.6, lead + (3,)).astype(np.float32)
                flat = p.reshape(-1, 3)
                for mode in ("signed", "gradient", "closest"):
                    path = "/v1/meshes/fan/query?mode=" + mode
                    status, got = post_npy(port, path, p)
                    status_flat, want = post_npy(port, path, flat)
                    self.assertEqual((status, status_flat), (200, 200), (lead, mode, got))
                    self.assertEqual(got.shape, lead + want.shape[1:], (lead, mode))
                    self.assertEqual(got.tobytes(), want.tobytes(), (lead, mode))
                status, got = post_npy(port, "/v1/volumes/fan16/query", p)
                self.assertEqual((status, got.shape), (200, lead), got)
            for bad in [np.zeros(3, np.float32), np.zeros((4, 2), np.float32),
                        np.zeros((2, 3, 2), np.float32)]:
                status, err = post_npy(port, "/v1/meshes/fan/query", bad)
                self.assertEqual((status, err["code"]), (422, "EINVAL"), bad.shape)
                self.assertIn("(..., 3)", err["message"])


def c_names(port):
    c = sdfclient.Client("http://127.0.0.1:%d" % port)
    try:
        return sorted(m["name"] for m in c.meshes())
    finally:
        c.close()


class ClientText(unittest.TestCase):
    """Error messages that quote a client's bytes stay UTF-8: a byte of no UTF-8 character
    becomes U+FFFD, so the JSON body and the binary ERROR frame stay readable."""

    def test_invalid_utf8_is_replaced(self):
        with Server() as s:
            conn = http.client.HTTPConnection("127.0.0.1", s.ports["http"], timeout=30)
            conn.request("POST", "/v1/meshes/demo/bake", b'{"\xffrder": 1}',
                         {"Content-Type": "application/json"})
            r = conn.getresponse()
            body = json.loads(r.read().decode("utf-8"))  # strict: fails on a stray byte
            conn.close()
            self.assertEqual(r.status, 422)
            self.assertIn("\ufffdrder", body["error"]["message"])
            with socket.create_connection(("127.0.0.1", s.bin_port), timeout=30) as sock:
                sock.sendall(harness.bin_query(7, np.zeros((1, 3), np.float32),
                                               name=b"\xe9t\xe9"))
                type_, rid, payload = harness.recv_frame(sock)
            self.assertEqual((type_, rid), (0x7F, 7))  # ERROR
            n = int.from_bytes(payload[2:4], "little")  # status, code, message
            message = payload[6 + n:].decode("utf-8")  # strict
            self.assertEqual(int.from_bytes(payload[4 + n:6 + n], "little"), len(message.encode()))
            self.assertIn("\ufffdt\ufffd", message)
            self.assertEqual([e for e in s.logs if "unparsed" in e], [])  # every line JSON


class ClientConnections(unittest.TestCase):
    """The Python client's kept-alive connection: reopened once the server closes it, and a
    request whose answer was lost sent again only where that does no harm."""

    def test_connection_the_server_closed_while_idle(self):
        with Server("--timeout", "1") as s:
            c = sdfclient.Client(s.url)
            self.addCleanup(c.close)
            c.health()
            sock = c._conn.sock
            # The server closes the idle connection after a second; the bake that follows
            # must go out on a new one, once, and not be lost to the old one.
            self.assertTrue(wait_until(lambda: select.select([sock], [], [], 0)[0], 10))
            job = c.bake("demo", volume="after_idle", resolution=8)
            self.assertEqual(c.wait(job)["state"], "done")
            self.assertEqual([j["id"] for j in c.jobs()], [job["id"]])

    def test_lost_answer_resent_only_for_queries(self):
        """A server that reads each request and closes without answering (as one that fell
        over after doing the work would): a query is sent twice, a bake once."""
        listener = socket.create_server(("127.0.0.1", 0))
        self.addCleanup(listener.close)
        received = []

        def serve():
            while True:
                try:
                    conn, _ = listener.accept()
                except OSError:
                    return
                with conn:
                    data = b""
                    while b"\r\n\r\n" not in data:
                        chunk = conn.recv(65536)
                        if not chunk:
                            break
                        data += chunk
                    head = data.split(b"\r\n\r\n")[0]
                    length = [int(line.split(b":")[1]) for line in head.split(b"\r\n")
                              if line.lower().startswith(b"content-length:")]
                    while length and len(data) - len(head) - 4 < length[0]:
                        data += conn.recv(65536)
                    received.append(head.split(b" ")[1].decode())

        threading.Thread(target=serve, daemon=True).start()
        c = sdfclient.Client(f"http://127.0.0.1:{listener.getsockname()[1]}")
        self.addCleanup(c.close)
        with self.assertRaises((ConnectionError, http.client.HTTPException)):
            c.bake("demo", volume="v", resolution=8)
        self.assertEqual(received, ["/v1/meshes/demo/bake"])
        with self.assertRaises((ConnectionError, http.client.HTTPException)):
            c.query("demo", np.zeros((2, 3), np.float32), form="json")
        self.assertEqual(received[1:], ["/v1/meshes/demo/query"] * 2)


if __name__ == "__main__":
    unittest.main(verbosity=2)
