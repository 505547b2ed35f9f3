"""Baked volumes through sdfd: bake jobs (progress, cancellation, limits, bad parameters),
downloads in every format against the library's own bake (sdf-volume, which calls
sdf_volume_bake directly: the same float32 bits), volume queries in every body form against
the library's evaluation of the downloaded EXR (and over the binary protocol's VOLUME_QUERY), and
the documented error statuses."""
import io
import json
import os
import re
import signal
import struct
import subprocess
import sys
import tempfile
import time
import unittest
import urllib.request

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "clients", "python"))
import sdfclient  # noqa: E402
import harness  # noqa: E402
from harness import DATA, Server, same_bits, wait_until  # noqa: E402

SDF_VOLUME = os.environ.get("SDF_VOLUME", "build/tests/bench/sdf-volume")


def library_bake(mesh, fmt, *args):
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "v." + fmt)
        subprocess.run([SDF_VOLUME, "bake", mesh, out, "--format", fmt, *args], check=True,
                       stdout=subprocess.DEVNULL)
        with open(out, "rb") as f:
            return f.read()


def library_eval(exr_bytes, points, interpolation, gradient):
    with tempfile.TemporaryDirectory() as d:
        paths = [os.path.join(d, n) for n in ("v.exr", "p.npy", "out.npy")]
        with open(paths[0], "wb") as f:
            f.write(exr_bytes)
        np.save(paths[1], points)
        subprocess.run([SDF_VOLUME, "eval", *paths, "--interpolation", interpolation]
                       + (["--gradient"] if gradient else []), check=True)
        return np.load(paths[2])


class Volumes(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.mesh = os.path.join(DATA, "fandisk.off")
        cls.server = Server("--mesh", f"fandisk={cls.mesh}", "--max-bake-queries", "20000000")
        cls.c = sdfclient.Client(cls.server.url)
        cls.bin = sdfclient.BinaryClient("127.0.0.1", cls.server.bin_port)

    @classmethod
    def tearDownClass(cls):
        cls.c.close()
        cls.bin.close()
        cls.server.stop()

    def bake(self, **params):
        job = self.c.bake("fandisk", **params)
        # The 202 shows the job as it stands when the reply is written: its thread may
        # already have started (or, for a tiny bake, finished) by then.
        self.assertIn(job["state"], ("queued", "running", "done"))
        self.assertEqual(job["href"], f"/v1/jobs/{job['id']}")
        return self.c.wait(job, timeout=120)

    def assert_binary_matches_http(self, name, points, order):
        """VOLUME_QUERY's four interpolation codes (0 trilinear, 1 nearest, 2 hermite, 3
        default) answer the bits of the HTTP query with the same interpolation name, and
        hermite on a zero-order volume is the same refusal over both."""
        for code, interpolation in enumerate(("trilinear", "nearest", "hermite", "default")):
            payload = (struct.pack("<BBHI", 1, code, len(name), len(points)) + name.encode()
                       + b"\0" * (-len(name) % 4) + points.tobytes())
            url = (f"/v1/volumes/{name}/query?mode=gradient&interpolation={interpolation}")
            if interpolation == "hermite" and order == 0:
                with self.assertRaises(sdfclient.SdfError) as over_binary:
                    self.bin._call(0x04, payload)
                with self.assertRaises(sdfclient.SdfError) as over_http:
                    self.c._request("POST", url, points.tobytes(),
                                    {"Content-Type": "application/octet-stream"})
                b, h = over_binary.exception, over_http.exception
                self.assertEqual((b.status, b.code, b.message), (h.status, h.code, h.message))
                self.assertEqual(b.status, 422)
                continue
            _, words = self.bin._call(0x04, payload)
            _, data = self.c._request("POST", url, points.tobytes(),
                                      {"Content-Type": "application/octet-stream"})
            self.assertEqual(words[8:], data, f"{name} {interpolation}: binary code {code}")
            via_client = self.bin.query_volume(name, points, interpolation, True)
            self.assertEqual(np.concatenate([via_client["distance"][:, None],
                                             via_client["gradient"]], 1).tobytes(), data,
                             f"{name} {interpolation}: BinaryClient")
        self.assertEqual(self.bin.query_volume(name, points)["distance"].tobytes(),
                         self.c.query_volume(name, points, form="octet")["distance"].tobytes(),
                         f"{name}: the clients' defaults differ")

    def test_bake_download_and_query_match_the_library(self):
        cases = [({"resolution": [20, 17, 14]}, ["--resolution", "20,17,14"]),
                 ({"resolution": 18, "order": 1}, ["--resolution", "18", "--order", "1"]),
                 ({"resolution": 16, "order": 1, "encoding": "packed32", "H": 2, "delta": 0.2},
                  ["--resolution", "16", "--order", "1", "--encoding", "packed32", "--H", "2",
                   "--delta", "0.2"]),
                 ({"resolution": 10, "order": 1, "normalize": "gradient"},
                  ["--resolution", "10", "--order", "1", "--normalize", "gradient"]),
                 ({"resolution": 12, "bounds": {"min": [-0.3, -0.3, -0.3], "max": [0.3, 0.2, 0.4]}},
                  ["--resolution", "12", "--lo", "-0.3,-0.3,-0.3", "--hi", "0.3,0.2,0.4"])]
        rng = np.random.default_rng(4)
        points = rng.uniform(-0.6, 0.6, (2000, 3)).astype(np.float32)
        for i, (params, args) in enumerate(cases):
            name = f"v{i}"
            status = self.bake(volume=name, **params)
            self.assertEqual((status["state"], status["progress"], status["volume"]), ("done", 1, name))
            meta = self.c.volume(name)
            dims = params["resolution"] if isinstance(params["resolution"], list) else [params["resolution"]] * 3
            self.assertEqual((meta["dims"], meta["order"], meta["mesh"]), (dims, params.get("order", 0), "fandisk"))
            for fmt in ("npy", "raw"):
                self.assertEqual(self.c.download(name, fmt, path=None) if fmt == "raw" else
                                 self.c._request("GET", f"/v1/volumes/{name}/data?format=npy")[1],
                                 library_bake(self.mesh, fmt, *args), f"{name} {fmt} differs")
            exr = self.c.download(name, "exr")
            for interpolation in ("trilinear", "nearest"):
                for gradient in (False, True):
                    ref = library_eval(exr, points, interpolation, gradient)
                    answers = {form: self.c.query_volume(name, points, interpolation, gradient, form)
                               for form in ("json", "octet", "npy")}
                    answers["binary"] = self.bin.query_volume(name, points, interpolation, gradient)
                    for form, r in answers.items():
                        self.assertTrue(same_bits(r["distance"], ref if ref.ndim == 1 else ref[:, 0]),
                                        f"{name} {interpolation} {form}: values")
                        if gradient:
                            self.assertTrue(same_bits(r["gradient"], ref[:, 1:4]),
                                            f"{name} {interpolation} {form}: gradient")
            # First order: hermite over HTTP, and the default (no interpolation given) is
            # hermite there, trilinear on zero-order volumes; hermite on zero order is refused.
            default = "hermite" if meta["order"] == 1 else "trilinear"
            ref = library_eval(exr, points, default, True)
            body = json.dumps({"points": points.tolist(), "mode": "gradient"}).encode()
            got = json.loads(urllib.request.urlopen(urllib.request.Request(
                f"{self.server.url}/v1/volumes/{name}/query", body,
                {"Content-Type": "application/json"}), timeout=60).read())
            self.assertTrue(same_bits(np.array(got["distance"], np.float32), ref[:, 0]),
                            f"{name}: the default interpolation is not {default}")
            self.assert_binary_matches_http(name, points, meta["order"])
            if meta["order"] == 1:
                for form in ("json", "octet", "npy"):
                    r = self.c.query_volume(name, points, "hermite", True, form)
                    self.assertTrue(same_bits(r["distance"], ref[:, 0]) and
                                    same_bits(r["gradient"], ref[:, 1:4]), f"{name} hermite {form}")
            else:
                with self.assertRaises(sdfclient.SdfError) as e:
                    self.c.query_volume(name, points[:1], "hermite")
                self.assertEqual(e.exception.status, 422)
                self.assertIn("needs a first-order volume", e.exception.message)
        array = self.c.download("v1", "npy")
        self.assertEqual((array.dtype, array.shape), (np.float32, (18, 18, 18, 4)))
        # The nearest node's value at a node, through the query route.
        meta = self.c.volume("v0")
        node = np.array([meta["origin"][a] + 3 * meta["spacing"][a] for a in range(3)], np.float32)
        got = self.c.query_volume("v0", node[None, :], "nearest")["distance"][0]
        self.assertEqual(got, self.c.download("v0", "npy")[3, 3, 3])
        names = [v["name"] for v in self.c.volumes()]
        self.assertEqual([n for n in names if n.startswith("v")], ["v0", "v1", "v2", "v3", "v4"])
        self.assertEqual(self.c.volume("v3")["normalize"], "gradient")
        text = self.c.metrics()
        self.assertGreaterEqual(harness.metric(text, "sdfd_volumes_loaded"), 4)
        self.assertGreater(harness.metric(text, "sdfd_volume_bytes"), 0)
        self.assertGreaterEqual(harness.metric(text, "sdfd_requests_total",
                                               'route="/v1/volumes/{name}/query",status="200"'), 1)

    def upload_error(self, client, body):
        with self.assertRaises(sdfclient.SdfError) as e:
            client.upload_volume("bad", body)
        return e.exception

    def test_copy_to_another_replica(self):
        self.bake(volume="copied", resolution=[9, 10, 11], order=1, encoding="packed32")
        exr = self.c.download("copied", "exr")
        points = np.random.default_rng(8).uniform(-0.5, 0.5, (500, 3)).astype(np.float32)
        here = self.c.query_volume("copied", points, gradient=True)
        with Server("--token", "t") as other:
            admin = sdfclient.Client(other.url, token="t")
            self.addCleanup(admin.close)
            with self.assertRaises(sdfclient.SdfError) as e:
                sdfclient.Client(other.url).upload_volume("copied", exr)
            self.assertEqual(e.exception.status, 401)
            meta = admin.upload_volume("copied", exr)
            self.assertEqual((meta["dims"], meta["encoding"]), ([9, 10, 11], "packed32"))
            there = admin.query_volume("copied", points, gradient=True)
            self.assertTrue(same_bits(here["distance"], there["distance"]))
            self.assertTrue(same_bits(here["gradient"], there["gradient"]))
            self.assertEqual(admin.download("copied", "exr"), exr)
            for bad in (exr[:len(exr) // 2], b"not an exr", self.c.download("copied", "npy").tobytes()):
                with self.assertRaises(sdfclient.SdfError, msg=bad[:10]) as e:
                    admin.upload_volume("bad", bad)
                self.assertIn(e.exception.status, (415, 422))  # not EXR / not an sdfd volume
            self.assertIn("takes the EXR file that .../data?format=exr gives: OpenEXR",
                          self.upload_error(admin, b"not an exr").message)
            # A download in another format is named as such, not put to the EXR reader.
            npy_file = self.c._request("GET", "/v1/volumes/copied/data?format=npy")[1]
            e = self.upload_error(admin, npy_file)
            self.assertEqual((e.status, e.code), (415, "EFORMAT"))
            self.assertIn("the body is a NumPy file", e.message)
            self.assertEqual([v["name"] for v in admin.volumes()], ["copied"])

    def test_surface_as_mesh(self):
        """GET /v1/volumes/{name}/mesh answers the surface in each format (the same triangles);
        POST stores it as a closed, manifold mesh whose distances are within a cell of the
        original's near the surface; bad arguments are named."""
        self.bake(volume="surf", resolution=48)
        cell = max(self.c.volume("surf")["spacing"])
        counts = {}
        for fmt, ctype in (("ply", "application/octet-stream"), ("obj", "model/obj"),
                           ("stl", "model/stl"), ("off", "text/plain")):
            resp, data = self.c._request("GET", f"/v1/volumes/surf/mesh?format={fmt}")
            self.assertEqual(resp.getheader("Content-Type"), ctype)
            self.assertEqual(resp.getheader("Content-Disposition"),
                             f'attachment; filename="surf.{fmt}"')
            counts[fmt] = int(resp.getheader("X-SDF-Triangles"))
            if fmt == "stl":
                self.assertEqual(struct.unpack_from("<I", data, 80)[0], counts[fmt])
                self.assertEqual(len(data), 84 + 50 * counts[fmt])
        self.assertEqual(len(set(counts.values())), 1, counts)
        self.assertGreater(counts["ply"], 1000)
        arrays = self.c.extract_mesh("surf")  # the Python client: arrays, a file, a mesh
        self.assertEqual(arrays["triangles"].shape, (counts["ply"], 3))
        self.assertEqual(arrays["triangles"].max() + 1, len(arrays["vertices"]))
        with tempfile.TemporaryDirectory() as d:
            out = self.c.extract_mesh("surf", path=os.path.join(d, "s.stl"))
            self.assertEqual(os.path.getsize(out), 84 + 50 * counts["ply"])
        self.assertTrue(self.c.extract_mesh("surf", mesh="surf_py", cap=True)["closed"])
        _, data = self.c._request("POST", "/v1/volumes/surf/mesh",
                                  json.dumps({"mesh": "surf_mesh"}).encode())
        report = json.loads(data)
        self.assertEqual((report["name"], report["triangles"], report["closed"],
                          report["edge_manifold"], report["flipped"]),
                         ("surf_mesh", counts["ply"], True, True, False), report)
        self.assertGreater(report["volume"], 0)
        rng = np.random.default_rng(4)
        pts = rng.uniform(-0.5, 0.5, (20000, 3)).astype(np.float32)
        orig = self.c.query("fandisk", pts)["distance"]
        got = self.c.query("surf_mesh", pts)["distance"]
        band = np.abs(orig) < 2 * cell
        self.assertGreater(band.sum(), 100)
        self.assertLess(np.abs(got - orig)[band].max(), cell)
        # iso and cap: an inner surface, and a cut one closed
        _, inner = self.c._request("GET", f"/v1/volumes/surf/mesh?iso={-cell}&format=off")
        self.assertLess(int(inner.split(b"\n")[1].split()[1]), counts["ply"])
        resp, _ = self.c._request("HEAD", "/v1/volumes/surf/mesh?cap=true&iso=0.01")
        self.assertGreater(int(resp.getheader("X-SDF-Triangles")), 0)
        for url, argument in (("format=3ds", "format"), ("format=auto", "format"),
                              ("iso=nan", "iso"), ("iso=1e999", "iso"), ("cap=maybe", "cap"),
                              ("level=0", "level")):
            with self.assertRaises(sdfclient.SdfError) as e:
                self.c._request("GET", f"/v1/volumes/surf/mesh?{url}")
            self.assertEqual(e.exception.status, 422, url)
            self.assertIn(argument, e.exception.message, url)
        for body, says in (({}, "mesh"), ({"mesh": ".x"}, "mesh"), ({"mesh": "m", "iso": "0"}, "iso"),
                           ({"mesh": "m", "cap": 1}, "cap"), ({"mesh": "m", "lod": 2}, "lod")):
            with self.assertRaises(sdfclient.SdfError) as e:
                self.c._request("POST", "/v1/volumes/surf/mesh", json.dumps(body).encode())
            self.assertEqual(e.exception.status, 422, body)
            self.assertIn(says, e.exception.message, body)
        with self.assertRaises(sdfclient.SdfError) as e:
            self.c._request("GET", "/v1/volumes/nope/mesh")
        self.assertEqual(e.exception.status, 404)
        # a first-order volume: dual contouring by default, closed; marching cubes on request;
        # dual contouring of a zero-order volume on request (normals from differences)
        self.bake(volume="surf1", resolution=32, order=1)
        dual = self.c.extract_mesh("surf1", mesh="surf1_dual")
        mc = self.c.extract_mesh("surf1", mesh="surf1_mc", method="marching_cubes")
        self.assertTrue(dual["closed"] and dual["edge_manifold"] and mc["closed"], (dual, mc))
        self.assertNotEqual(dual["vertices"], mc["vertices"])
        dual0 = self.c.extract_mesh("surf", mesh="surf_dual0", method="dual_contouring")
        self.assertTrue(dual0["closed"] and dual0["edge_manifold"], dual0)
        with self.assertRaises(sdfclient.SdfError) as e:
            self.c.extract_mesh("surf", method="dual")
        self.assertEqual(e.exception.status, 422)
        self.assertIn("method", e.exception.message)

    def test_bake_ops_and_mesh_in_one_job(self):
        """A bake with "ops" and "mesh": one job, whose end leaves the volume and its surface as
        a mesh, closed and manifold."""
        job = self.bake(volume="e2e", resolution=40, ops=[{"round": 0.01}], mesh="e2e-mesh")
        self.assertEqual(job["state"], "done", job)
        report = self.c.mesh("e2e-mesh")
        self.assertEqual((report["closed"], report["edge_manifold"], report["flipped"]),
                         (True, True, False), report)
        self.assertEqual(report["triangles"], len(self.c.extract_mesh("e2e")["triangles"]))
        with self.assertRaises(sdfclient.SdfError) as e:
            self.c.bake("fandisk", volume="e2e", resolution=8, mesh=".hidden")
        self.assertEqual((e.exception.status, e.exception.code), (422, "EINVAL"))
        self.assertIn("mesh", e.exception.message)
        self.c.delete("e2e-mesh")

    def test_filtered_bake(self):
        raw = self.bake(volume="raw8", resolution=8)
        filtered = self.bake(volume="filtered8", resolution=8, field="filtered",
                             filter={"samples": 8, "seed": 3})
        self.assertEqual((raw["state"], filtered["state"]), ("done", "done"))
        self.assertTrue(self.c.volume("filtered8")["filtered"])
        a, b = self.c.download("raw8", "npy"), self.c.download("filtered8", "npy")
        self.assertFalse(np.array_equal(a, b))
        self.assertLess(np.abs(a - b).max(), 0.1 * np.abs(a).max())

    def test_coordinates_as_mesh_queries(self):
        """A volume query holds its points to the mesh queries' rule, on both protocols and in
        every body form: NaN, Inf or beyond +-1e18 is 422 ENONFINITE naming the point, and
        1e18 itself is answered, finite: a first-order volume's boundary planes extended that
        far stay inside float32."""
        self.bake(volume="far1", resolution=8, order=1)
        rule = "has a coordinate that is NaN, Inf or beyond +-1e18"
        for far in (1e30, 3e38, 2e18, -1e19, float("inf"), float("nan")):
            points = np.array([[0, 0, 0], [0, far, 0]], np.float32)
            for form in ("octet", "npy", "json"):
                if form == "json" and not np.isfinite(far):
                    continue  # JSON has no Inf or NaN to send
                with self.assertRaises(sdfclient.SdfError, msg=(far, form)) as e:
                    self.c.query_volume("far1", points, form=form)
                self.assertEqual((e.exception.status, e.exception.code), (422, "ENONFINITE"))
                self.assertIn("point 1 " + rule, e.exception.message)
            for what in (False, True):
                with self.assertRaises(sdfclient.SdfError, msg=(far, what)) as e:
                    self.bin.query_volume("far1", points, "default", what)
                self.assertEqual((e.exception.status, e.exception.code), (422, "ENONFINITE"))
                self.assertIn("point 1 " + rule, e.exception.message)
        edge = [[1e18, -1e18, 1e18], [0, 0, 0]]
        octet = self.c.query_volume("far1", edge, "trilinear", form="octet")["distance"]
        self.assertTrue(np.all(np.isfinite(octet)), octet)
        self.assertEqual(self.bin.query_volume("far1", edge, "trilinear")["distance"].tobytes(),
                         octet.tobytes())
        text = self.c._request("POST", "/v1/volumes/far1/query",
                               json.dumps({"points": edge, "interpolation": "trilinear"}),
                               {"Content-Type": "application/json"})[1]
        self.assertEqual(np.array(json.loads(text)["distance"], np.float32).tobytes(),
                         octet.tobytes())
        self.c.delete_volume("far1")

    def test_cancel_and_forget(self):
        # The filtered field is baked by queries (~18 M here, near the server's per-request
        # cap; about a second in a release build): cancelled as soon as it runs.
        job = self.c.bake("fandisk", volume="big", resolution=34, order=1, field="filtered",
                          filter={"samples": 16})
        deadline = time.time() + 30
        while self.c.job(job["id"])["state"] == "queued" and time.time() < deadline:
            time.sleep(0.01)
        s = self.c.cancel(job["id"])
        self.assertTrue(s["cancel_requested"])
        deadline = time.time() + 30
        while True:  # until it ends, every look says the cancel is pending
            s = self.c.job(job["id"])
            if s["state"] not in ("queued", "running") or time.time() > deadline:
                break
            self.assertTrue(s.get("cancel_requested"), s)
            time.sleep(0.01)
        self.assertEqual(s["state"], "canceled")
        self.assertNotIn("cancel_requested", s)
        with self.assertRaises(sdfclient.SdfError) as e:
            self.c.volume("big")
        self.assertEqual(e.exception.status, 404)
        self.assertIn(job["id"], [j["id"] for j in self.c.jobs()])
        self.assertEqual(self.c.cancel(job["id"])["state"], "canceled")  # forgets it
        with self.assertRaises(sdfclient.SdfError) as e:
            self.c.job(job["id"])
        self.assertEqual(e.exception.status, 404)

    def test_zero_margin_is_the_mesh_box(self):
        # The library reads a zero margin as its default (5 % of the diagonal); asked for
        # explicitly, it means the mesh's own box.
        box = self.c.mesh("fandisk")["bbox"]
        self.assertEqual(self.bake(volume="box0", resolution=9, margin=0)["state"], "done")
        meta = self.c.volume("box0")
        far = [meta["origin"][a] + 8 * meta["spacing"][a] for a in range(3)]
        np.testing.assert_allclose(meta["origin"], box["min"], rtol=0, atol=1e-6)
        np.testing.assert_allclose(far, box["max"], rtol=0, atol=1e-6)
        self.assertEqual(self.bake(volume="box1", resolution=9)["state"], "done")
        self.assertLess(self.c.volume("box1")["origin"][0], box["min"][0] - 0.01)
        for name in ("box0", "box1"):
            self.c.delete_volume(name)

    def test_bad_requests(self):
        bad = [({"resolution": 1}, 422, "'resolution' is 1, out of range (2..4096)"),
               ({"resolution": 0}, 422, "'resolution' is 0, out of range (2..4096)"),
               ({"resolution": [8, 8, 5000]}, 422, "'resolution' is 5000, out of range"),
               ({"order": 1e12}, 422, "'order' is 1e+12, out of range"),
               ({"resolution": [8, 8]}, 422, "resolution"),
               ({"resolution": 8.5}, 422, "resolution"),
               ({"order": 2}, 422, "order"),
               ({"order": 1, "H": 9}, 422, "H"),
               ({"order": 1, "delta": 0.7}, 422, "Delta"),
               ({"encoding": "packed32"}, 422, "first-order"),
               ({"encoding": "png"}, 422, "encoding"),
               ({"order": 1, "normalize": "all"}, 422, "normalize"),
               ({"bounds": {"min": [0, 0, 0], "max": [1, -1, 1]}}, 422, "min < max"),
               # all zero would read as "no bounds" to the library
               ({"bounds": {"min": [0, 0, 0], "max": [0, 0, 0]}}, 422, "min < max"),
               # 0 would read as "the default" to the library
               ({"filter": {"cap": 0}}, 422, "cap must be a positive"),
               ({"filter": {"smooth": {"sphere": [0, 0, 0, 1], "depth": 0}}}, 422,
                "depth must be a positive"),
               ({"bounds": [0, 1]}, 422, "bounds"),
               ({"resolutoin": 8}, 422, "unknown key 'resolutoin'"),
               ({"field": "smooth"}, 422, "field"),
               ({"field": "raw", "filter": {"samples": 8}}, 422, "filter"),
               ({"filter": {"kernel": "bump", "b": 1}}, 422, "8 f_c / 9"),
               ({"filter": {"sample_gradient": True}}, 422, "sample_gradient"),
               ({"volume": ".hidden"}, 422, "volume"),
               ({"resolution": 300}, 413, "--max-bake-queries"),
               ({"order": 1, "resolution": 100}, 413, "--max-bake-queries")]
        for body, status, says in bad:
            with self.assertRaises(sdfclient.SdfError, msg=str(body)) as e:
                self.c.bake("fandisk", **body)
            self.assertEqual(e.exception.status, status, body)
            self.assertIn(says, e.exception.message, body)
        for method, path, body, status in [
                ("POST", "/v1/meshes/nope/bake", "{}", 404),
                ("POST", "/v1/meshes/fandisk/bake", "not json", 400),
                ("POST", "/v1/meshes/fandisk/bake", "[1]", 422),
                ("POST", "/v1/meshes/fandisk/bake", '{"resolution": 8, "resolution": 4000}', 422),
                ("GET", "/v1/meshes/fandisk/bake", None, 405),
                ("GET", "/v1/jobs/nope", None, 404),
                ("DELETE", "/v1/jobs/nope", None, 404),
                ("GET", "/v1/volumes/nope", None, 404),
                ("DELETE", "/v1/volumes/nope", None, 404),
                ("GET", "/v1/volumes/nope/data", None, 404),
                ("POST", "/v1/volumes/nope/query", '{"points": [[0, 0, 0]]}', 404),
                ("POST", "/v1/volumes/x", "", 405),
                ("GET", "/v1/volumes/x/other", None, 404)]:
            req = urllib.request.Request(self.server.url + path, method=method,
                                         data=body.encode() if body is not None else None,
                                         headers={"Content-Type": "application/json"})
            try:
                urllib.request.urlopen(req, timeout=30)
                self.fail(f"{method} {path} succeeded")
            except urllib.error.HTTPError as e:
                self.assertEqual(e.code, status, f"{method} {path}")
                self.assertIn("error", json.loads(e.read()))
        self.bake(volume="q", resolution=8)
        for kwargs, says in [({"interpolation": "cubic"}, "interpolation"),
                             ({"points": [[0, float("nan"), 0]]}, "NaN")]:
            with self.assertRaises(sdfclient.SdfError) as e:
                self.c.query_volume("q", kwargs.pop("points", [[0, 0, 0]]), form="octet", **kwargs)
            self.assertEqual(e.exception.status, 422)
            self.assertIn(says, e.exception.message)
        for call, status in [(lambda: self.bin.query_volume("nope", [[0, 0, 0]]), 404),
                             (lambda: self.bin.query_volume("q", [[0, float("nan"), 0]]), 422)]:
            with self.assertRaises(sdfclient.SdfError) as e:
                call()
            self.assertEqual(e.exception.status, status)
        bad_mode = struct.pack("<BBHI", 7, 0, 1, 1) + b"q\0\0\0" + b"\0" * 12
        with self.assertRaises(sdfclient.SdfError) as e:
            self.bin._call(0x04, bad_mode)
        self.assertEqual(e.exception.status, 422)
        bad_interpolation = struct.pack("<BBHI", 0, 4, 1, 1) + b"q\0\0\0" + b"\0" * 12
        with self.assertRaises(sdfclient.SdfError) as e:
            self.bin._call(0x04, bad_interpolation)
        self.assertEqual((e.exception.status, e.exception.code), (422, "EINVAL"))
        self.assertIn("3 default", e.exception.message)
        with self.assertRaises(ValueError):
            self.bin.query_volume("q", [[0, 0, 0]], "cubic")
        self.assertEqual(self.bin.query_volume("q", [[0, 0, 0]])["distance"].shape, (1,))  # still open
        with self.assertRaises(sdfclient.SdfError) as e:
            self.c.download("q", "png")
        self.assertEqual(e.exception.status, 422)
        self.c.delete_volume("q")
        self.assertNotIn("q", [v["name"] for v in self.c.volumes()])


class Limits(unittest.TestCase):
    def test_queued_bakes_run_in_arrival_order(self):
        with Server("--max-bakes", "1") as s:
            c = sdfclient.Client(s.url)
            self.addCleanup(c.close)
            ids = [c.bake("demo", volume=f"q{i}", resolution=22, order=1)["id"] for i in range(4)]
            finished, seen_running = [], set()
            deadline = time.time() + 120
            while len(finished) < len(ids) and time.time() < deadline:
                states = {j["id"]: j["state"] for j in c.jobs()}
                running = [i for i in ids if states[i] == "running"]
                self.assertLessEqual(len(running), 1, "--max-bakes 1")
                seen_running.update(running)
                finished += [i for i in ids if states[i] == "done" and i not in finished]
                time.sleep(0.005)
            self.assertEqual(finished, ids)


    def test_surface_over_max_triangles(self):
        """A surface past --max-triangles: 413 from the routes; a bake that names a mesh fails
        with the reason, and its volume stays."""
        with Server("--max-triangles", "13000") as s:  # the demo knot has 12,288
            c = sdfclient.Client(s.url)
            self.addCleanup(c.close)
            job = c.bake("demo", volume="k", resolution=64, mesh="k-mesh")
            with self.assertRaises(sdfclient.SdfError) as e:
                c.wait(job, timeout=60)
            self.assertEqual(e.exception.code, "ELIMIT")
            self.assertIn("--max-triangles", e.exception.message)
            self.assertEqual(c.volume("k")["dims"], [64, 64, 64])
            self.assertNotIn("k-mesh", [m["name"] for m in c.meshes()])
            for method, body in (("GET", None), ("POST", b'{"mesh": "k-mesh"}')):
                with self.assertRaises(sdfclient.SdfError) as e:
                    c._request(method, "/v1/volumes/k/mesh", body)
                self.assertEqual(e.exception.status, 413, method)

    def test_memory_limit_token_and_shutdown(self):
        with Server("--token", "t", "--max-volume-bytes", "8000000") as s:
            anon, admin = sdfclient.Client(s.url), sdfclient.Client(s.url, token="t")
            self.addCleanup(anon.close)
            self.addCleanup(admin.close)
            with self.assertRaises(sdfclient.SdfError) as e:
                anon.bake("demo", resolution=8)
            self.assertEqual(e.exception.status, 401)
            admin.wait(admin.bake("demo", resolution=16))  # 16 KiB, ~4 MB while baking
            # 75^3 floats (1.7 MB) would fit; with what the bake works in, they do not.
            with self.assertRaises(sdfclient.SdfError) as e:
                admin.bake("demo", volume="big", resolution=75)
            self.assertEqual(e.exception.status, 413)
            self.assertIn("--max-volume-bytes", e.exception.message)
            m = re.search(r"needs (\d+) bytes \((\d+) for the volume, (\d+) to work in\)",
                          e.exception.message)
            self.assertIsNotNone(m, e.exception.message)
            need, volume, working = map(int, m.groups())
            self.assertEqual(volume, 75 ** 3 * 4)
            self.assertEqual(need, volume + working)
            self.assertLess(volume + 16 ** 3 * 4, 8000000)
            self.assertGreater(need, 8000000 - 16 ** 3 * 4)
            self.assertEqual(anon.query_volume("demo", [[0, 0, 0]])["distance"].shape, (1,))
        # SIGTERM during a long bake (the filtered field's ~60 MB of working memory: the
        # default limit): it is canceled and the server exits promptly.
        with Server("--token", "t") as s:
            admin = sdfclient.Client(s.url, token="t")
            self.addCleanup(admin.close)
            job = admin.bake("demo", volume="long", resolution=13, order=1, field="filtered",
                             filter={"samples": 64})["id"]
            self.assertTrue(wait_until(lambda: admin.job(job)["state"] == "running", 30))
            t0 = time.time()
            self.assertEqual(s.stop(signal.SIGTERM), 0)
            self.assertLess(time.time() - t0, 20)


if __name__ == "__main__":
    unittest.main(verbosity=2)
