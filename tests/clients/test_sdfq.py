"""sdfq, the command line (docs/sdfq.md), against a real sdfd: every subcommand; its
answers bit-equal to the server's HTTP octet-stream answers for the same points (npy and
CSV outputs, npy and CSV inputs, many pipelined requests); its npy output byte-equal to the
HTTP npy answer; the token over both protocols; bad input files, unknown names and an
unreachable server, each with its documented exit code and a one-line message. Over TLS
(certificates made by certtool as tests/server/test_tls.py makes them): --cacert with an
https:// server and --bin-tls, the same bits as plain, and a wrong CA, a missing CA file and
TLS on the wrong side each refused with a clear line. Through a proxy that cuts the binary
connection as a dying replica would, sdfq's query re-sends and answers the same bits."""
import io
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import unittest

import numpy as np

HERE = os.path.dirname(__file__)
sys.path.insert(0, os.path.join(HERE, "..", "..", "clients", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "server"))
import sdfclient  # noqa: E402
from harness import DATA, Server  # noqa: E402
from test_tls import make_ca, make_server_cert  # noqa: E402

SDFQ = os.environ.get("SDFQ", "build/clients/c/sdfq")
MODES = ["signed", "distance", "gradient", "closest", "filtered", "filtered-gradient"]
WORDS = {"signed": 1, "distance": 1, "gradient": 4, "closest": 5, "filtered": 1,
         "filtered-gradient": 4}


def free_port():
    """A loopback port nobody listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def csv_words(text, words):
    """sdfq's CSV output -> (N, W) uint32 words in the wire layout."""
    lines = text.strip().splitlines()[1:]
    out = np.zeros((len(lines), words), np.uint32)
    for i, line in enumerate(lines):
        fields = line.split(",")
        assert len(fields) == words, line
        for w, f in enumerate(fields):
            if words == 5 and w == 4:
                out[i, w] = int(f)
            else:
                out[i, w] = np.float32(float(f)).view(np.uint32)
    return out


class CutProxy:
    """A loopback proxy to a binary port whose first connection is closed once it has relayed
    `cut` bytes of replies (a replica dying behind a load balancer); later ones relay all."""

    def __init__(self, port, cut):
        self.port, self.cut, self.connections = port, cut, 0
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(0.1)
        self.stopping = False
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    @property
    def address(self):
        return f"127.0.0.1:{self.listener.getsockname()[1]}"

    def _serve(self):
        while not self.stopping:
            try:
                client, _ = self.listener.accept()
            except socket.timeout:
                continue
            self.connections += 1
            limit = self.cut if self.connections == 1 else None
            upstream = socket.create_connection(("127.0.0.1", self.port))
            threading.Thread(target=self._pipe, args=(client, upstream, None), daemon=True).start()
            threading.Thread(target=self._pipe, args=(upstream, client, limit), daemon=True).start()

    @staticmethod
    def _pipe(src, dst, limit):
        relayed = 0
        try:
            while limit is None or relayed < limit:
                data = src.recv(65536 if limit is None else min(65536, limit - relayed))
                if not data:
                    break
                dst.sendall(data)
                relayed += len(data)
        except OSError:
            pass
        for s in (src, dst):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()

    def close(self):
        self.stopping = True
        self.thread.join()
        self.listener.close()


class Sdfq(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server("--mesh", f"fandisk={os.path.join(DATA, 'fandisk.off')}")
        cls.http = sdfclient.Client(cls.server.url)
        cls.tmp = tempfile.TemporaryDirectory()
        rng = np.random.default_rng(11)
        cls.points = rng.uniform(-0.3, 0.3, (2500, 3)).astype(np.float32)
        # the same mesh over HTTPS and --bin-tls, its certificate signed by cls.ca
        ca = make_ca(cls.tmp.name, "ca")
        cls.ca = ca[0]
        cls.other_ca = make_ca(cls.tmp.name, "other-ca")[0]
        cert, key = make_server_cert(cls.tmp.name, "server", ca, 0x4004)
        cls.tls = Server("--mesh", f"fandisk={os.path.join(DATA, 'fandisk.off')}",
                         "--tls-cert", cert, "--tls-key", key, "--bin-tls")
        cls.https = f"https://127.0.0.1:{cls.tls.ports['http']}"

    @classmethod
    def tearDownClass(cls):
        cls.http.close()
        cls.tls.stop()
        cls.tmp.cleanup()
        cls.server.stop()

    def path(self, name):
        return os.path.join(self.tmp.name, name)

    def sdfq(self, *args, stdin=None, env_extra=None, server=None):
        server = server or self.server
        env = dict(os.environ, SDFD_URL=server.url, SDFD_BIN=f"127.0.0.1:{server.bin_port}")
        for name in ("SDFD_TOKEN", "SDFD_CACERT", "SDFD_BIN_TLS"):
            env.pop(name, None)
        env.update(env_extra or {})
        return subprocess.run([SDFQ, *args], input=stdin, capture_output=True, env=env,
                              timeout=120)

    def octet(self, mode, points, mesh="fandisk", extra=""):
        """The server's HTTP octet-stream answer: (N, W) uint32 words."""
        _, data = self.http._request(
            "POST", f"/v1/meshes/{mesh}/query?mode={mode}{extra}", points.tobytes(),
            {"Content-Type": "application/octet-stream"})
        return np.frombuffer(data, np.uint32).reshape(len(points), WORDS[mode])

    def assertOk(self, r):
        self.assertEqual(r.returncode, 0, r.stderr.decode())

    def assertFails(self, r, code, *words):
        err = r.stderr.decode()
        self.assertEqual(r.returncode, code, err)
        self.assertEqual(err.count("\n"), 1, f"one line on stderr: {err!r}")
        self.assertTrue(err.startswith("sdfq"), err)
        for w in words:
            self.assertIn(w, err)

    # ---- query ----

    def test_every_mode_npy_and_csv_bit_equal_to_http(self):
        np.save(self.path("p.npy"), self.points)
        for mode in MODES:
            extra = "&samples=8" if mode.startswith("filtered") else ""
            flags = ["--samples", "8"] if extra else []
            ref = self.octet(mode, self.points, extra=extra)
            out = self.path(f"{mode}.npy")
            self.assertOk(self.sdfq("query", "fandisk", self.path("p.npy"), "--mode", mode,
                                    "-o", out, *flags))
            a = np.load(out)
            words = (np.stack([a["distance"].view(np.uint32), *a["closest"].view(np.uint32).T,
                               a["triangle"]], 1) if mode == "closest"
                     else a.view(np.uint32).reshape(len(self.points), -1))
            self.assertTrue(np.array_equal(words, ref), mode)
            _, npy = self.http._request(
                "POST", f"/v1/meshes/fandisk/query?mode={mode}{extra}", open(self.path("p.npy"),
                                                                              "rb").read(),
                {"Content-Type": "application/x-npy"})
            self.assertEqual(open(out, "rb").read(), npy, f"{mode}: npy bytes as HTTP's")
            r = self.sdfq("query", "fandisk", self.path("p.npy"), "--mode", mode, *flags)
            self.assertOk(r)
            self.assertTrue(np.array_equal(csv_words(r.stdout.decode(), WORDS[mode]), ref), mode)

    def test_csv_inputs_and_stdin(self):
        pts = self.points[:300]
        ref = self.octet("gradient", pts)
        rows = "\n".join(f"{x!r},{y!r},{z!r}" for x, y, z in pts.astype(float).tolist())
        for name, text in (("plain.csv", rows + "\n"), ("header.csv", "x,y,z\n" + rows),
                           ("crlf.csv", "x, y, z\r\n" + rows.replace("\n", "\r\n") + "\r\n\r\n")):
            with open(self.path(name), "w", newline="") as f:
                f.write(text)
            r = self.sdfq("query", "fandisk", self.path(name), "--mode", "gradient")
            self.assertOk(r)
            self.assertTrue(np.array_equal(csv_words(r.stdout.decode(), 4), ref), name)
        r = self.sdfq("query", "fandisk", "-", "--mode", "gradient", stdin=rows.encode())
        self.assertTrue(np.array_equal(csv_words(r.stdout.decode(), 4), ref), "CSV on stdin")
        buf = io.BytesIO()
        np.save(buf, pts.astype(np.float64))  # float64 points go out as float32
        r = self.sdfq("query", "fandisk", "--mode", "gradient", "-o", "-", "--output-format",
                      "npy", stdin=buf.getvalue())
        self.assertOk(r)
        self.assertTrue(np.array_equal(np.load(io.BytesIO(r.stdout)).view(np.uint32), ref))

    def test_csv_round_trip(self):
        """Points written as sdfq writes floats (%.9g) read back as the same float32, and the
        CSV answer parses back to the octet answer's bits."""
        pts = self.points[:200]
        with open(self.path("in.csv"), "w") as f:
            f.writelines("%.9g,%.9g,%.9g\n" % tuple(p) for p in pts.astype(float).tolist())
        out = self.path("round.csv")
        self.assertOk(self.sdfq("query", "fandisk", self.path("in.csv"), "--mode", "closest",
                                "-o", out))
        self.assertTrue(np.array_equal(csv_words(open(out).read(), 5), self.octet("closest", pts)))

    def test_pipelining_many_requests(self):
        rng = np.random.default_rng(3)
        pts = rng.uniform(-0.4, 0.4, (30001, 3)).astype(np.float32)
        np.save(self.path("many.npy"), pts)
        out = self.path("many-out.npy")
        self.assertOk(self.sdfq("query", "fandisk", self.path("many.npy"), "--mode", "closest",
                                "--batch", "97", "-o", out))  # 310 requests, the last short
        a = np.load(out)
        ref = self.octet("closest", pts)
        self.assertTrue(np.array_equal(a["triangle"], ref[:, 4]))
        self.assertTrue(np.array_equal(a["distance"].view(np.uint32), ref[:, 0]))
        requests = [e for e in self.server.logs
                    if e.get("event") == "request" and e.get("proto") == "binary"
                    and e.get("method") == "QUERY" and e.get("points") == 97]
        self.assertGreaterEqual(len(requests), 309, "split into --batch requests")

    # ---- refusals and bad input ----

    def test_bad_input_files(self):
        np.save(self.path("good.npy"), self.points[:10])
        data = open(self.path("good.npy"), "rb").read()
        cases = {
            "trunc.npy": (data[:-5], "npy"),
            "header.npy": (data[:40], "npy"),
            "shape.npy": (None, "shape (N, 3)"),
            "big.npy": (None, "little-endian"),
            "bad.csv": (b"x,y,z\n1,2,3\n4,5,6\n7,8\n", "line 4"),
            "word.csv": (b"1,2,3\n1,two,3\n", "line 2"),
            "extra.csv": (b"1,2,3,4\n", "line 1"),
        }
        np.save(self.path("shape.npy"), np.zeros((4, 2), np.float32))
        np.save(self.path("big.npy"), np.zeros((4, 3), ">f4"))
        for name, (content, words) in cases.items():
            if content is not None:
                with open(self.path(name), "wb") as f:
                    f.write(content)
            r = self.sdfq("query", "fandisk", self.path(name), "-o", self.path("never.csv"))
            self.assertFails(r, 4, name, words)
            self.assertFalse(os.path.exists(self.path("never.csv")))
        self.assertFails(self.sdfq("query", "fandisk", self.path("missing.csv")), 4, "missing")
        self.assertFails(self.sdfq("upload", "m", self.path("missing.off")), 4, "missing")

    def test_server_refusals_exit_2(self):
        np.save(self.path("p2.npy"), self.points[:5])
        self.assertFails(self.sdfq("query", "nope", self.path("p2.npy")), 2, "404", "ENOTFOUND")
        bad = self.points[:5].copy()
        bad[3, 1] = np.nan
        np.save(self.path("nan.npy"), bad)
        self.assertFails(self.sdfq("query", "fandisk", self.path("nan.npy")), 2, "ENONFINITE")
        self.assertFails(self.sdfq("download", "nope", "-o", self.path("x.exr")), 2, "ENOTFOUND")
        self.assertFalse(os.path.exists(self.path("x.exr")), "no file from a refusal")
        self.assertFails(self.sdfq("delete", "nope"), 2, "404")
        self.assertFails(self.sdfq("bake", "fandisk", "--resolution", "4096"), 2, "413")

    def test_unreachable_server_exit_3(self):
        port = free_port()
        np.save(self.path("p3.npy"), self.points[:5])
        r = self.sdfq("query", "fandisk", self.path("p3.npy"), "--bin", f"127.0.0.1:{port}")
        self.assertFails(r, 3, "cannot connect", str(port))
        self.assertFails(self.sdfq("meshes", env_extra={"SDFD_BIN": f"127.0.0.1:{port}"}), 3,
                         str(port))
        r = self.sdfq("volumes", "--server", f"http://127.0.0.1:{port}")
        self.assertFails(r, 3, str(port))

    def test_usage_and_help(self):
        for cmd in ("query", "query-volume", "meshes", "upload", "bake", "ops", "download",
                    "delete", "volumes", "slice"):
            r = self.sdfq(cmd, "--help")
            self.assertOk(r)
            self.assertIn(f"usage: sdfq {cmd}", r.stdout.decode())
            self.assertIn("Exit: 0 ok", r.stdout.decode())
        self.assertOk(self.sdfq("--help"))
        r = self.sdfq("--version")
        self.assertOk(r)
        self.assertEqual(r.stdout.decode(), "sdfq %s\n" % os.environ["SDF_VERSION"])
        self.assertFails(self.sdfq("query", "fandisk", "--frobnicate"), 1, "--frobnicate")
        self.assertFails(self.sdfq("query", "fandisk", "--mode", "loud"), 1, "loud")
        self.assertFails(self.sdfq("frobnicate"), 1, "frobnicate")
        self.assertFails(self.sdfq("download", "v"), 1, "-o")
        self.assertFails(self.sdfq("meshes", "--bin", "nocolon"), 1, "HOST:PORT")
        # field operations: NAME=number, checked before anything is sent
        self.assertFails(self.sdfq("ops", "v"), 1, "at least one operation")
        for op in ("round", "round=", "=0.1", "round=abc", "round=0.1x", "round=inf"):
            self.assertFails(self.sdfq("ops", "v", op), 1, "NAME=R", op)
            self.assertFails(self.sdfq("bake", "fandisk", "--op", "round=0.05", "--op", op), 1,
                             "NAME=R", op)
        self.assertFails(self.sdfq("ops", "v", "round=0.1", "--iterations", "-1"), 1,
                         "--iterations")

    # ---- the other subcommands ----

    def test_slice(self):
        args = ("--axis", "y", "--at", "0.02", "--size", "80", "--mode", "filtered",
                "--samples", "8", "--seed", "4")
        self.assertOk(self.sdfq("slice", "fandisk", "-o", self.path("s.png"), *args))
        _, png = self.http._request("GET", "/v1/meshes/fandisk/slice.png?axis=y&at=0.02&size=80"
                                    "&mode=filtered&samples=8&seed=4")
        with open(self.path("s.png"), "rb") as f:
            self.assertEqual(f.read(), png)
        self.assertTrue(png.startswith(b"\x89PNG"))
        self.assertOk(self.sdfq("slice", "fandisk", "-o", self.path("s.npy"), *args))
        got = np.load(self.path("s.npy"))
        _, data = self.http._request("GET", "/v1/meshes/fandisk/slice.png?axis=y&at=0.02&size=80"
                                     "&mode=filtered&samples=8&seed=4&format=npy")
        self.assertEqual(got.tobytes(), np.load(io.BytesIO(data)).tobytes())
        self.assertEqual(max(got.shape), 80)
        r = self.sdfq("slice", "fandisk", "-o", self.path("never.png"), "--axis", "w")
        self.assertFails(r, 2, "422", "axis")
        self.assertFalse(os.path.exists(self.path("never.png")))
        self.assertFails(self.sdfq("slice", "nope", "--volume", "-o", self.path("n.png")), 2,
                         "ENOTFOUND")
        self.assertFails(self.sdfq("slice", "fandisk"), 1, "-o")

    def test_mesh(self):
        self.http.wait(self.http.bake("fandisk", volume="mv", resolution=20))
        self.assertOk(self.sdfq("mesh", "mv", "-o", self.path("m.stl"), "--iso", "0.01"))
        _, stl = self.http._request("GET", "/v1/volumes/mv/mesh?format=stl&iso=0.01")
        with open(self.path("m.stl"), "rb") as f:
            self.assertEqual(f.read(), stl)
        r = self.sdfq("mesh", "mv", "--mesh", "mv-mesh", "--cap")
        self.assertOk(r)
        report = json.loads(r.stdout)
        self.assertEqual((report["name"], report["closed"]), ("mv-mesh", True))
        self.assertFails(self.sdfq("mesh", "mv", "-o", self.path("x.ply"), "--iso", "abc"), 2,
                         "422", "iso")
        self.assertFails(self.sdfq("mesh", "mv"), 1, "-o FILE or --mesh")
        self.assertFails(self.sdfq("mesh", "nope", "-o", self.path("n.ply")), 2, "ENOTFOUND")
        self.http.delete("mv-mesh")
        self.http.delete_volume("mv")

    def test_meshes_upload_bake_download_delete(self):
        self.assertOk(self.sdfq("upload", "cow", os.path.join(DATA, "cow.off")))
        r = self.sdfq("meshes")
        self.assertOk(r)
        rows = [line.split("\t") for line in r.stdout.decode().splitlines()]
        listed = {m["name"]: m for m in self.http.meshes()}
        self.assertEqual(sorted(row[0] for row in rows), sorted(listed))
        for row in rows:
            self.assertEqual(int(row[1]), listed[row[0]]["triangles"])
        r = self.sdfq("bake", "cow", "--volume", "cv", "--resolution", "24", "--order", "1",
                      "--wait")
        self.assertOk(r)
        self.assertIn('"state":"done"', r.stdout.decode())
        self.assertIn("bake cv: done 100%", r.stderr.decode(), "plain lines off a terminal")
        self.assertNotIn("\r", r.stderr.decode())
        self.assertIn("cv\t24x24x24\torder 1", self.sdfq("volumes").stdout.decode())
        pts = self.points[:700]
        np.save(self.path("v.npy"), pts)
        # each --interpolation, and none (the server's default: hermite on this first-order
        # volume), answers the bits of the HTTP query with that interpolation
        answers = {}
        for interp in (None, "default", "trilinear", "nearest", "hermite"):
            args = ("--interpolation", interp) if interp else ()
            r = self.sdfq("query-volume", "cv", self.path("v.npy"), "--gradient", "-o",
                          self.path("vout.npy"), *args)
            self.assertOk(r)
            q = f"&interpolation={interp}" if interp else ""
            _, data = self.http._request("POST", f"/v1/volumes/cv/query?mode=gradient{q}",
                                         pts.tobytes(),
                                         {"Content-Type": "application/octet-stream"})
            answers[interp] = np.load(self.path("vout.npy")).tobytes()
            self.assertEqual(answers[interp], data, f"--interpolation {interp}")
        self.assertEqual(answers[None], answers["hermite"])
        self.assertNotEqual(answers["hermite"], answers["trilinear"])
        self.assertFails(self.sdfq("query-volume", "cv", self.path("v.npy"), "--interpolation",
                                   "cubic"), 1, "cubic", "hermite")
        for fmt in ("exr", "npy", "raw"):
            out = self.path(f"cv.{fmt}")
            self.assertOk(self.sdfq("download", "cv", "-o", out))
            _, data = self.http._request("GET", f"/v1/volumes/cv/data?format={fmt}")
            self.assertEqual(open(out, "rb").read(), data, fmt)
        job = self.sdfq("bake", "cow", "--volume", "cv2", "--resolution", "8")
        self.assertOk(job)
        self.assertTrue(job.stdout.decode().strip(), "the job id")
        self.http.wait(job.stdout.decode().strip())
        r = self.sdfq("query-volume", "cv2", self.path("v.npy"), "--interpolation", "hermite")
        self.assertFails(r, 2, "422", "needs a first-order volume")
        self.assertOk(self.sdfq("delete", "--volume", "cv", "cv2"))
        self.assertEqual(self.http.volumes(), [])
        self.assertOk(self.sdfq("delete", "cow"))
        self.assertNotIn("cow", self.sdfq("meshes").stdout.decode())

    def test_ops_and_bake_op(self):
        r = self.sdfq("bake", "fandisk", "--volume", "fsrc", "--resolution", "20", "--wait")
        self.assertOk(r)
        r = self.sdfq("ops", "fsrc", "round=0.05", "fillet=0.03", "--volume", "fout",
                      "--solver", "sussman", "--iterations", "5", "--wait")
        self.assertOk(r)
        job = json.loads(r.stdout)
        self.assertEqual((job["state"], job["kind"], job["source"], job["volume"]),
                         ("done", "ops", "fsrc", "fout"))
        self.assertIsInstance(job["caveats"], list)
        self.assertIn("ops fout: done 100%", r.stderr.decode(), "plain lines off a terminal")
        self.assertEqual(self.http.volume("fout")["dims"], self.http.volume("fsrc")["dims"])
        # the same chain started without --wait: the job id, then the job's record
        r = self.sdfq("ops", "fsrc", "round=0.05", "fillet=0.03", "--volume", "fout2",
                      "--solver", "sussman", "--iterations", "5")
        self.assertOk(r)
        done = self.http.wait(r.stdout.decode().strip())
        self.assertEqual((done["kind"], done["volume"]), ("ops", "fout2"))
        self.assertEqual(self.http.download("fout2", "raw"), self.http.download("fout", "raw"))
        # bake --op, repeated: the operations in order, on the baked grid
        r = self.sdfq("bake", "fandisk", "--volume", "fbaked", "--resolution", "20",
                      "--op", "round=0.05", "--op=fillet=0.03", "--solver", "sussman",
                      "--iterations", "5", "--wait")
        self.assertOk(r)
        self.assertIsInstance(json.loads(r.stdout)["caveats"], list)
        self.assertEqual(self.http.download("fbaked", "raw"), self.http.download("fout", "raw"),
                         "a bake with --op is the bake then the ops")
        self.assertFails(self.sdfq("ops", "fsrc", "sharpen=0.1"), 2, "422", "sharpen")
        self.assertFails(self.sdfq("ops", "nope", "round=0.05"), 2, "404")
        self.assertFails(self.sdfq("bake", "fandisk", "--order", "1", "--op", "round=0.05"), 2,
                         "422")
        self.assertOk(self.sdfq("delete", "--volume", "fsrc", "fout", "fout2", "fbaked"))

    def test_token(self):
        with Server("--token", "s3cret", "--auth-queries") as srv:
            np.save(self.path("t.npy"), self.points[:20])
            ok = self.sdfq("query", "demo", self.path("t.npy"), server=srv,
                           env_extra={"SDFD_TOKEN": "s3cret"})
            self.assertOk(ok)
            ref = sdfclient.Client(srv.url, token="s3cret").query("demo", self.points[:20],
                                                                  form="octet")
            self.assertTrue(np.array_equal(csv_words(ok.stdout.decode(), 1).view(np.float32)[:, 0],
                                           ref["distance"]))
            self.assertFails(self.sdfq("query", "demo", self.path("t.npy"), "--token", "wrong",
                                       server=srv), 2, "401", "EUNAUTHORIZED")
            self.assertFails(self.sdfq("query", "demo", self.path("t.npy"), server=srv), 2,
                             "EUNAUTHORIZED")
            self.assertFails(self.sdfq("upload", "c", os.path.join(DATA, "cow.off"), server=srv),
                             2, "401")
            self.assertOk(self.sdfq("upload", "c", os.path.join(DATA, "cow.off"), "--token",
                                    "s3cret", server=srv))


    # ---- TLS (the second server) and re-sending ----

    def tls_env(self, ca=None, **extra):
        return {"SDFD_URL": self.https, "SDFD_BIN": f"127.0.0.1:{self.tls.bin_port}",
                "SDFD_CACERT": ca or self.ca, **extra}

    def test_query_and_meshes_over_tls_bit_equal(self):
        np.save(self.path("tp.npy"), self.points)
        ref = self.octet("gradient", self.points)
        for env in (self.tls_env(SDFD_BIN_TLS="1"), self.tls_env(SDFD_BIN_TLS="true")):
            r = self.sdfq("query", "fandisk", self.path("tp.npy"), "--mode", "gradient",
                          "--batch", "300", env_extra=env)
            self.assertOk(r)
            self.assertTrue(np.array_equal(csv_words(r.stdout.decode(), 4), ref))
        out = self.path("tls-out.npy")
        self.assertOk(self.sdfq("query", "fandisk", self.path("tp.npy"), "--mode", "gradient",
                                "-o", out, "--bin-tls", "--cacert", self.ca,
                                "--server", self.https, "--bin", f"127.0.0.1:{self.tls.bin_port}"))
        self.assertTrue(np.array_equal(np.load(out).view(np.uint32), ref), "--bin-tls --cacert")
        r = self.sdfq("meshes", "--bin-tls", env_extra=self.tls_env())
        self.assertOk(r)
        self.assertIn("fandisk\t", r.stdout.decode())

    def test_https_commands_with_cacert(self):
        r = self.sdfq("volumes", env_extra=self.tls_env())
        self.assertOk(r)
        self.assertOk(self.sdfq("upload", "cow", os.path.join(DATA, "cow.off"), "--cacert",
                                self.ca, "--server", self.https))
        self.assertIn("cow\t", self.sdfq("meshes", "--bin-tls", env_extra=self.tls_env())
                      .stdout.decode())
        self.assertOk(self.sdfq("delete", "cow", env_extra=self.tls_env()))

    def test_tls_refusals(self):
        np.save(self.path("tr.npy"), self.points[:10])
        q = ("query", "fandisk", self.path("tr.npy"))
        self.assertFails(self.sdfq(*q, "--bin-tls", env_extra=self.tls_env(self.other_ca)), 3,
                         "certificate is not trusted", "--cacert")
        self.assertFails(self.sdfq("volumes", env_extra=self.tls_env(self.other_ca)), 3,
                         "cannot reach", self.https)
        self.assertFails(self.sdfq(*q, "--bin-tls", "--cacert", self.path("none.pem")), 4,
                         "none.pem")
        self.assertFails(self.sdfq(*q, env_extra=self.tls_env()), 3, "closed", "--bin-tls")
        self.assertFails(self.sdfq(*q, "--bin-tls", "--cacert", self.ca), 3,
                         "TLS handshake", "leave out --bin-tls")
        self.assertFails(self.sdfq("meshes", env_extra=self.tls_env(SDFD_BIN_TLS="maybe")), 1,
                         "SDFD_BIN_TLS")

    def test_resent_after_a_cut(self):
        pts = self.points[:2000]
        np.save(self.path("cut.npy"), pts)
        ref = self.octet("signed", pts)
        for server, extra in ((self.server, []),
                              (self.tls, ["--bin-tls", "--cacert", self.ca])):
            # 20 requests of 100 points, replies of 424 bytes: the cut falls in the third (past
            # the TLS handshake's few KB)
            proxy = CutProxy(server.bin_port, 4000 if extra else 1000)
            try:
                r = self.sdfq("query", "fandisk", self.path("cut.npy"), "--batch", "100",
                              "--bin", proxy.address, *extra, server=server)
                self.assertOk(r)
                self.assertTrue(np.array_equal(csv_words(r.stdout.decode(), 1), ref))
                self.assertEqual(proxy.connections, 2, "one new connection")
            finally:
                proxy.close()


if __name__ == "__main__":
    unittest.main(verbosity=2)
