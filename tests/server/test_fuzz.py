"""Mutated requests against the real sdfd, from a fixed seed: valid binary frames (every
QUERY mode, FILTER blocks, VOLUME_QUERY, HELLO, MESHES, AUTH) and valid HTTP bodies (queries in
JSON, octet-stream and npy, bakes, volume queries and uploads) with random bytes flipped,
inserted, dropped or cut off, and length fields replaced. Whatever arrives, the server must
answer with a 2xx/4xx status or an ERROR frame (or close a connection it cannot follow), never
crash or hang, keep answering a known query with the same bits throughout, give back every
byte of --max-buffered-bytes it held for them, and exit cleanly on SIGTERM. In the sanitizer
build, any report on its stderr fails the test."""
import http.client
import io
import json
import os
import random
import socket
import struct
import sys
import time
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "clients", "python"))
import sdfclient  # noqa: E402
from harness import DATA, Server, metric, same_bits, wait_until  # noqa: E402

SEED = 20261202
ROUNDS = int(os.environ.get("SDF_FUZZ_ROUNDS", "400"))  # per protocol


def mutate(rng, data):
    """One to four random edits of a byte string."""
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        kind = rng.randrange(6)
        at = rng.randrange(len(b) + 1)
        if kind == 0 and b:  # flip bits of a byte
            b[at % len(b)] ^= 1 << rng.randrange(8)
        elif kind == 1 and b:  # an extreme byte
            b[at % len(b)] = rng.choice((0, 0x7F, 0x80, 0xFF))
        elif kind == 2:  # insert bytes
            b[at:at] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 8)))
        elif kind == 3 and b:  # drop bytes
            del b[at:at + rng.randint(1, 8)]
        elif kind == 4:  # cut off
            del b[at:]
        elif len(b) >= 4:  # a 32-bit field replaced by an extreme value
            at = rng.randrange(len(b) - 3)
            b[at:at + 4] = struct.pack("<I", rng.choice((0, 1, 0x7FFFFFFF, 0xFFFFFFFF,
                                                         1 << 20, 1 << 31)))
    return bytes(b)


class Fuzz(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server("--mesh", f"fandisk={os.path.join(DATA, 'fandisk.off')}",
                            "--max-points", "2000", "--max-body-bytes", "200000",
                            "--max-bake-queries", "3000000", "--timeout", "2")
        cls.c = sdfclient.Client(cls.server.url)
        cls.probe = np.array([[0.1, 0.2, 0.3], [0.5, -0.4, 0.2]], np.float32)
        cls.expected = cls.c.query("fandisk", cls.probe)["distance"]
        job = cls.c.bake("fandisk", volume="vol", resolution=12, order=1)
        cls.c.wait(job, timeout=120)
        cls.exr = cls.c.download("vol", "exr")

    @classmethod
    def tearDownClass(cls):
        cls.c.close()
        code = cls.server.stop()  # raises on a sanitizer report (harness.py)
        if code != 0:
            raise AssertionError(f"sdfd exited {code}")

    def assert_nothing_held(self):
        # Every byte of --max-buffered-bytes reserved for the damaged requests came back.
        self.assertTrue(wait_until(lambda: metric(self.c.metrics(), "sdfd_buffered_bytes") == 0,
                                   20), metric(self.c.metrics(), "sdfd_buffered_bytes"))

    def assert_alive(self):
        c = sdfclient.Client(self.server.url)
        try:
            self.assertTrue(same_bits(c.query("fandisk", self.probe)["distance"], self.expected))
        finally:
            c.close()

    # ---- binary protocol ----

    def frames(self):
        B = sdfclient.BinaryClient
        pts = np.random.default_rng(1).uniform(-0.5, 0.5, (5, 3)).astype(np.float32)
        payloads = [(0x01, b"fuzz"), (0x02, b""), (0x05, b"token")]
        for mode in ("signed", "distance", "gradient", "closest"):
            payloads.append((0x03, B._query_payload("fandisk", pts, mode, "auto")))
        for f in ({"samples": 8}, {"samples": 4, "kernel": "bump", "cap": 0.05, "b": 0.04},
                  {"samples": 4, "smooth": {"sphere": [0, 0, 0, 0.3]}},
                  {"samples": 4, "smooth": {"mesh": "fandisk"}}, {"samples": 8, "min_samples": 2}):
            payloads.append((0x03, B._query_payload("fandisk", pts, "filtered-gradient", "auto", f)))
        vq = struct.pack("<BBHI", 1, 0, 3, len(pts)) + b"vol\0" + pts.tobytes()
        payloads.append((0x04, vq))
        return payloads

    def exchange(self, raw):
        """Send raw bytes on a fresh connection; read replies until the server goes quiet or
        closes. Returns the frame types received."""
        s = socket.create_connection(("127.0.0.1", self.server.bin_port), timeout=10)
        types = []
        try:
            s.sendall(raw)
            s.shutdown(socket.SHUT_WR)  # nothing more: a half frame waits out the timeout
            buf = b""
            while True:
                chunk = s.recv(1 << 16)
                if not chunk:
                    break
                buf += chunk
            while len(buf) >= 16:
                magic, version, type_, _, rid, length = sdfclient.BinaryClient.HEADER.unpack(buf[:16])
                self.assertEqual((magic, version), (b"SDFP", 1))
                types.append(type_)
                buf = buf[16 + length:]
        except (ConnectionResetError, BrokenPipeError):
            pass
        finally:
            s.close()
        return types

    def test_binary_frames(self):
        rng = random.Random(SEED)
        frames = self.frames()
        seen = {0x83: 0, 0x7F: 0}
        for i in range(ROUNDS):
            type_, payload = rng.choice(frames)
            header = struct.pack("<4sBBHII", b"SDFP", 1, type_, 0, i + 1, len(payload))
            raw = header + payload
            if rng.random() < 0.5:
                raw = header + mutate(rng, payload)  # the declared length may now be wrong
            else:
                raw = mutate(rng, raw)
            # A valid frame after it: answered unless the garbage closed the connection.
            good = next(f for f in frames if f[0] == 0x03)
            raw += struct.pack("<4sBBHII", b"SDFP", 1, good[0], 0, 99999, len(good[1])) + good[1]
            types = self.exchange(raw)
            self.assertTrue(set(types) <= {0x81, 0x82, 0x83, 0x85, 0x7F}, types)
            for t in seen:
                seen[t] += t in types
            if i % 50 == 0:
                self.assert_alive()
        self.assert_alive()
        # The mutations reach both sides: frames still answered, and frames refused. Answered
        # are about 5-8 % of the rounds (a mutated coordinate past 1e18 is refused by mesh and
        # volume queries alike, and the valid frame after the garbage is answered unless the
        # garbage closed the connection first).
        self.assertGreater(seen[0x83], ROUNDS // 40, seen)
        self.assertGreater(seen[0x7F], ROUNDS // 5, seen)
        self.assert_nothing_held()

    # ---- HTTP ----

    def http(self, method, path, body, ctype):
        conn = http.client.HTTPConnection("127.0.0.1", self.server.ports["http"], timeout=30)
        try:
            conn.request(method, path, body=body, headers={"Content-Type": ctype})
            r = conn.getresponse()
            data = r.read()
            return r.status, data
        finally:
            conn.close()

    def test_http_bodies(self):
        rng = random.Random(SEED + 1)
        pts = np.random.default_rng(2).uniform(-0.5, 0.5, (6, 3)).astype(np.float32)
        npy = io.BytesIO()
        np.save(npy, pts)
        query = "/v1/meshes/fandisk/query"
        cases = [
            ("POST", query, json.dumps({"points": pts.tolist(), "mode": "gradient"}).encode(),
             "application/json"),
            ("POST", query, json.dumps({"points": pts.tolist(), "mode": "filtered",
                                        "filter": {"samples": 8, "cap": 0.05,
                                                   "smooth": {"box": [-1, -1, -1, 1, 1, 1]}}}).encode(),
             "application/json"),
            ("POST", query + "?mode=closest", pts.tobytes(), "application/octet-stream"),
            ("POST", query + "?mode=filtered&samples=4&smooth_sphere=0,0,0,0.2", npy.getvalue(),
             "application/x-npy"),
            ("POST", "/v1/meshes/fandisk/bake",
             json.dumps({"volume": "fz", "resolution": [6, 7, 8], "order": 1, "H": 1,
                         "bounds": {"min": [-0.5, -0.5, -0.5], "max": [0.5, 0.5, 0.5]}}).encode(),
             "application/json"),
            ("POST", "/v1/volumes/vol/query",
             json.dumps({"points": pts.tolist(), "mode": "gradient",
                         "interpolation": "nearest"}).encode(), "application/json"),
            ("PUT", "/v1/volumes/up", self.exr, "image/x-exr"),
        ]
        answered = refused = 0
        for i in range(ROUNDS):
            method, path, body, ctype = rng.choice(cases)
            if ctype != "image/x-exr" or rng.random() < 0.3:  # EXR: mostly the 4 kB header
                body = mutate(rng, body)
            else:
                body = mutate(rng, body[:4096]) + body[4096:]
            status, data = self.http(method, path, body, ctype)
            self.assertTrue(200 <= status < 300 or 400 <= status < 500, (status, data[:200]))
            if status >= 400:
                self.assertIn(b'"error"', data)
            answered += status < 300
            refused += status >= 400
            if i % 50 == 0:
                self.assert_alive()
        self.assert_alive()
        self.assertGreater(answered, ROUNDS // 40, (answered, refused))
        self.assertGreater(refused, ROUNDS // 2, (answered, refused))
        self.assert_nothing_held()


if __name__ == "__main__":
    unittest.main(verbosity=2)
