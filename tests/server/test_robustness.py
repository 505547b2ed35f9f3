"""sdfd under bad input, load and shutdown:
  - a catalogue of bad requests, each answered with its status and error code (or, for
    garbage binary frames, an ERROR frame and a closed connection), after which the server
    still answers /healthz and real queries;
  - a client that sends half a request and stalls is cut off by the timeout, others unaffected;
  - 64 concurrent clients of small requests all get correct answers, and /metrics proves
    that batches coalesced more than one request;
  - SIGTERM with requests in flight: every one of them is answered, then exit 0; binary
    clients are shed (idle connections closed at once, busy ones once answered)."""
import http.client
import json
import os
import signal
import socket
import struct
import sys
import threading
import time
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "clients", "python"))
import sdfclient  # noqa: E402
from harness import (BIN_HEADER, Server, bin_query, metric, recv_frame,  # noqa: E402
                     wait_until)


def raw_http(port, method, path, body=b"", headers=None):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        c.request(method, path, body=body, headers=headers or {})
        r = c.getresponse()
        data = r.read()
        return r.status, (json.loads(data) if data and r.getheader("Content-Type", "").startswith(
            "application/json") else data)
    finally:
        c.close()


class BadInput(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server("--max-body-bytes", "100000", "--max-points", "1000", "--timeout", "2")
        cls.port = int(cls.server.url.rsplit(":", 1)[1])

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()

    def assert_alive(self):
        self.assertEqual(raw_http(self.port, "GET", "/healthz")[0], 200)
        c = sdfclient.Client(self.server.url)
        d = c.query("demo", np.array([[3.35, 0, 0]], np.float32))["distance"]
        c.close()
        self.assertLess(abs(d[0]), 1e-5)

    def expect(self, status, code, method, path, body=b"", headers=None):
        got, data = raw_http(self.port, method, path, body, headers)
        self.assertEqual(got, status, f"{method} {path} {body[:60]!r}: {data}")
        if code:
            self.assertEqual(data["error"]["code"], code, data)
            self.assertTrue(data["error"]["message"])
        self.assert_alive()

    Q = "/v1/meshes/demo/query"
    JSON = {"Content-Type": "application/json"}
    OCTET = {"Content-Type": "application/octet-stream"}

    def test_json_catalogue(self):
        for body, status, code in [
            (b'{"points": [0,0,', 400, "ESYNTAX"),
            (b'not json', 400, "ESYNTAX"),
            (b'{"points": [[0,0,0]]} trailing', 400, "ESYNTAX"),
            (b'{} trailing', 400, "ESYNTAX"),
            (b'{"points": [0,0,0],}', 400, "ESYNTAX"),
            (b'{"points": [0,0,0] "mode": "signed"}', 400, "ESYNTAX"),
            (b'{"points": "abc"}', 422, "EINVAL"),
            (b'{"points": [[0,0]]}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": 7}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "fast"}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "sign": "guess"}', 422, "EINVAL"),
            (b'{"points": [0,0,0, 1e999,0,0]}', 422, "ENONFINITE"),
            (b'{"nopoints": 1}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": 3}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"kernal": "bump"}}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"samples": 0}}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"samples": 2.5}}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"cap": "big"}}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"cap": -1}}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"kernel": "bump", "cap": 0.01, '
             b'"b": 0.5}}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"smooth": {"sphere": [0,0,0]}}}',
             422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"smooth": {"sphere": [0,0,0,-1]}}}',
             422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"smooth": {"box": [0,0,0,1,1,1], '
             b'"mesh": "demo"}}}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"smooth": {"mesh": "nope"}}}',
             404, "ENOTFOUND"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"samples": 8, "min_samples": 9}}',
             422, "EINVAL"),
            (b'{"points": [' + b"0," * 3003 + b"0]}", 413, "ELIMIT"),
            # A key we read, given twice (JSON leaves it undefined; both were taken).
            (b'{"points": [[0,0,0]], "points": [[1,1,1]]}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "signed", "mode": "distance"}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {}, "filter": {}}', 422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"samples": 8, "samples": 9}}',
             422, "EINVAL"),
            (b'{"points": [0,0,0], "mode": "filtered", "filter": {"smooth": {"sphere": [0,0,0,1], '
             b'"sphere": [0,0,0,2]}}}', 422, "EINVAL"),
        ]:
            with self.subTest(body=body[:40]):
                self.expect(status, code, "POST", self.Q, body, BadInput.JSON)

    def test_http_catalogue(self):
        nan = struct.pack("<6f", 0, 0, 0, float("nan"), 0, 0)
        self.expect(415, "EFORMAT", "POST", self.Q, b"{}", {"Content-Type": "text/plain"})
        self.expect(400, "ESYNTAX", "POST", self.Q, b"\0" * 13, self.OCTET)
        self.expect(422, "ENONFINITE", "POST", self.Q, nan, self.OCTET)
        # Finite but beyond +-1e18 (Embree aborts on rays from there): refused for every
        # sign method and form, before it can fail a batch shared with other requests.
        far = struct.pack("<6f", 0, 0, 0, 0, 2e18, 0)
        for sign in ("auto", "pseudonormal", "winding", "raycast", "none"):
            got, data = raw_http(self.port, "POST", self.Q + "?sign=" + sign, far, self.OCTET)
            self.assertEqual((got, data["error"]["code"]), (422, "ENONFINITE"), sign)
            self.assertIn("point 1 has a coordinate that is NaN, Inf or beyond +-1e18",
                          data["error"]["message"])
        self.expect(422, "ENONFINITE", "POST", self.Q, b'{"points": [[0, 1e19, 0]]}', self.JSON)
        b = sdfclient.BinaryClient("127.0.0.1", self.server.bin_port)
        with self.assertRaises(sdfclient.SdfError) as e:
            b.query("demo", np.array([[0, 0, 0], [1e30, 0, 0]]), sign="raycast")
        self.assertEqual((e.exception.status, e.exception.code), (422, "ENONFINITE"))
        self.assertEqual(len(b.query("demo", np.array([[1e18, 0, 0]]), sign="raycast")["distance"]), 1)
        b.close()
        self.expect(413, "ELIMIT", "POST", self.Q, b"\0" * 12 * 1001, self.OCTET)
        self.expect(413, "ELIMIT", "POST", self.Q, b"\0" * 120000, self.OCTET)
        self.expect(404, "ENOTFOUND", "POST", "/v1/meshes/nope/query", b"\0" * 12, self.OCTET)
        self.expect(422, "EINVAL", "POST", self.Q + "?mode=fast", b"\0" * 12, self.OCTET)
        self.expect(422, "EINVAL", "POST", self.Q + "?sign=maybe", b"\0" * 12, self.OCTET)
        self.expect(422, "EINVAL", "POST", self.Q + "?mode=filtered&kernel=box", b"\0" * 12,
                    self.OCTET)
        self.expect(422, "EINVAL", "POST", self.Q + "?mode=filtered&samples=9999", b"\0" * 12,
                    self.OCTET)
        self.expect(422, "EINVAL", "POST", self.Q + "?mode=filtered&grid=maybe", b"\0" * 12,
                    self.OCTET)
        self.expect(422, "EINVAL", "POST", self.Q + "?mode=filtered&smooth_box=0,0,0,1,1", b"\0" * 12,
                    self.OCTET)
        self.expect(404, "ENOTFOUND", "POST", self.Q + "?mode=filtered&smooth_mesh=nope",
                    b"\0" * 12, self.OCTET)
        # Cost: 1000 points x (64 + 1) queries > 16 x max-points (1000): refused up front.
        self.expect(413, "ELIMIT", "POST", self.Q + "?mode=filtered", b"\0" * 12 * 1000,
                    self.OCTET)
        self.expect(200, None, "POST", self.Q + "?mode=filtered&samples=8", b"\0" * 12 * 100,
                    self.OCTET)
        self.expect(404, "ENOTFOUND", "GET", "/nowhere")
        self.expect(405, "EMETHOD", "GET", self.Q)
        for path in ("/v1/meshes", "/v1/meshes/demo", "/healthz"):  # HEAD wherever GET
            got, data = raw_http(self.port, "HEAD", path)
            self.assertEqual((got, data), (200, b""), path)
        self.expect(405, "EMETHOD", "POST", "/v1/meshes")
        self.expect(422, "EINVAL", "GET", "/v1/meshes/..secret")
        # A %00 in the path is no end of the name ("demo%00x" is not the mesh "demo"), nor of
        # an argument; other escapes decode as ever.
        self.expect(422, "EINVAL", "GET", "/v1/meshes/demo%00x")
        self.expect(422, "EINVAL", "POST", self.Q + "?mode=signed%00x", b"\0" * 12, self.OCTET)
        self.expect(200, None, "GET", "/v1/meshes/de%6Do")
        npy = {"Content-Type": "application/x-npy"}
        self.expect(415, "EFORMAT", "POST", self.Q, b"\x93NUMPY garbage", npy)
        self.expect(400, "ESYNTAX", "POST", self.Q, b"\x93NUMPY\x01\x00\x76\x00{'descr'", npy)
        self.expect(422, "EINDEX", "PUT", "/v1/meshes/x?format=off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n")

    def test_length_required_and_oversize_header(self):
        # Chunked upload: no Content-Length -> 411, before any body is read.
        s = socket.create_connection(("127.0.0.1", self.port))
        s.sendall(b"POST /v1/meshes/demo/query HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                  b"Transfer-Encoding: chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n")
        self.assertIn(b" 411 ", s.recv(4096).split(b"\r\n")[0] + b" ")
        s.close()
        # A huge declared body is refused from the header alone (the body is never sent).
        s = socket.create_connection(("127.0.0.1", self.port))
        s.sendall(b"POST /v1/meshes/demo/query HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                  b"Content-Length: 99999999999\r\n\r\n")
        self.assertIn(b" 413 ", s.recv(4096).split(b"\r\n")[0] + b" ")
        s.close()
        self.assert_alive()

    def test_stalled_http_client(self):
        s = socket.create_connection(("127.0.0.1", self.port))
        s.sendall(b"POST /v1/meshes/demo/query HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                  b"Content-Length: 100\r\n\r\n{\"points\": [")
        self.assert_alive()  # others are served while it stalls
        s.settimeout(10)
        t0 = time.time()
        data = s.recv(4096)  # the server closes it after --timeout 2
        self.assertLess(time.time() - t0, 9)
        self.assertEqual(data, b"")
        s.close()
        self.assert_alive()

    def bin_connect(self):
        s = socket.create_connection(("127.0.0.1", self.server.bin_port))
        s.settimeout(10)
        return s

    @staticmethod
    def recv_frame(s):
        head = b""
        while len(head) < 16:
            chunk = s.recv(16 - len(head))
            if not chunk:
                return None
            head += chunk
        magic, _, type_, _, rid, length = struct.unpack("<4sBBHII", head)
        body = b""
        while len(body) < length:
            body += s.recv(length - len(body))
        return type_, rid, body

    def test_binary_garbage_closes_connection(self):
        for junk in (b"GET / HTTP/1.1\r\n\r\n", b"SDFP\x02\x03\0\0" + b"\0" * 8,
                     b"SDFP\x01\x03\0\0\1\0\0\0" + struct.pack("<I", 1 << 31)):
            s = self.bin_connect()
            s.sendall(junk)
            type_, rid, body = self.recv_frame(s)
            self.assertEqual((type_, rid), (0x7F, 0))
            self.assertIsNone(self.recv_frame(s), "connection stays open after garbage")
            s.close()
        self.assert_alive()

    def test_binary_bad_requests_keep_connection(self):
        b = sdfclient.BinaryClient("127.0.0.1", self.server.bin_port)
        for name, pts, mode, code in [("nope", np.zeros((1, 3)), "signed", "ENOTFOUND"),
                                      ("demo", np.full((1, 3), np.nan), "signed", "ENONFINITE"),
                                      ("demo", np.zeros((1001, 3)), "signed", "ELIMIT")]:
            with self.assertRaises(sdfclient.SdfError) as e:
                b.query(name, pts, mode=mode)
            self.assertEqual(e.exception.code, code)
        # A bump wider than eq. (7) allows: refused with the bound in the message.
        with self.assertRaises(sdfclient.SdfError) as e:
            b.query("demo", np.zeros((2, 3)), mode="filtered",
                    filter={"kernel": "bump", "cap": 0.01, "b": 0.5})
        self.assertEqual((e.exception.status, e.exception.code), (422, "EINVAL"))
        self.assertIn("8 f_c / 9", e.exception.message)
        # Over HTTP an explicit 0 would read as "the default" to the library, so it is refused
        # (the binary protocol's fixed FILTER block documents 0 as "the default").
        http = sdfclient.Client(self.server.url)
        for f, says, forms in [({"cap": 0}, "cap must be a positive", ("json", "octet")),
                               ({"a": -1}, "a must be a positive", ("json", "octet", "binary")),
                               ({"smooth": {"sphere": [0, 0, 0, 1], "scale": 0}},
                                "scale must be a positive", ("json", "octet"))]:
            for form in forms:
                with self.assertRaises(sdfclient.SdfError, msg=f"{f} {form}") as e:
                    (b.query("demo", np.zeros((2, 3)), mode="filtered", filter=f) if form == "binary"
                     else http.query("demo", np.zeros((2, 3)), mode="filtered", filter=f,
                                     form=form))
                self.assertEqual((e.exception.status, e.exception.code), (422, "EINVAL"))
                self.assertIn(says, e.exception.message)
        http.close()
        with self.assertRaises(sdfclient.SdfError) as e:
            b.query("demo", np.zeros((2, 3)), mode="filtered", filter={"smooth": {"mesh": "nope"}})
        self.assertEqual((e.exception.status, e.exception.code), (404, "ENOTFOUND"))
        # A wrongly sized QUERY and an unknown type: ERROR replies, connection kept.
        b.sock.sendall(struct.pack("<4sBBHII", b"SDFP", 1, 3, 0, 77, 9) + b"\0" * 9)
        b.sock.sendall(struct.pack("<4sBBHII", b"SDFP", 1, 0x42, 0, 78, 0))
        replies = {b._recv()[0]: None for _ in range(2)}
        self.assertEqual(set(replies), {77, 78})
        self.assertEqual(len(b.query("demo", np.zeros((4, 3)))["distance"]), 4)
        b.close()

    def test_binary_truncated_frame_times_out(self):
        s = self.bin_connect()
        s.sendall(struct.pack("<4sBBHII", b"SDFP", 1, 3, 0, 5, 1000) + b"\0" * 10)
        t0 = time.time()
        self.assertIsNone(self.recv_frame(s))  # closed after --timeout 2
        self.assertLess(time.time() - t0, 9)
        s.close()
        self.assert_alive()


class Limits(unittest.TestCase):
    def test_busy_queue_gets_429(self):
        # A 1 s batch window keeps the first job queued; with room for 10 queued points,
        # a second job arriving meanwhile is refused with 429, then everything recovers.
        with Server("--batch-window-us", "1000000", "--max-queued-points", "10") as s:
            first = {}
            t = threading.Thread(target=lambda: first.update(
                r=sdfclient.Client(s.url).query("demo", np.zeros((8, 3)))))
            t.start()
            self.assertTrue(wait_until(lambda: metric(sdfclient.Client(s.url).metrics(),
                                                      "sdfd_queue_depth") == 1, 5))
            with self.assertRaises(sdfclient.SdfError) as e:
                sdfclient.Client(s.url).query("demo", np.zeros((8, 3)), form="octet")
            self.assertEqual((e.exception.status, e.exception.code), (429, "EBUSY"))
            b = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            with self.assertRaises(sdfclient.SdfError) as e:
                b.query("demo", np.zeros((8, 3)))
            self.assertEqual(e.exception.code, "EBUSY")
            t.join(10)
            self.assertEqual(len(first["r"]["distance"]), 8)
            self.assertEqual(len(b.query("demo", np.zeros((8, 3)))["distance"]), 8)
            b.close()

    def test_bodies_held_at_once_are_bounded(self):
        # Room for one 80 kB body at a time over all connections (each connection's own
        # limit is 100 kB): while one is half received, a second, on HTTP or the binary
        # protocol, gets 429; once the first is done, the same request is taken.
        with Server("--max-body-bytes", "100000", "--max-points", "10000",
                    "--max-buffered-bytes", "150000") as s:
            port = int(s.url.rsplit(":", 1)[1])
            body = b'{"points": [[0, 0, 0]]}'.ljust(80000)
            held = socket.create_connection(("127.0.0.1", port), timeout=30)
            held.sendall(b"POST /v1/meshes/demo/query HTTP/1.1\r\nHost: x\r\n"
                         b"Content-Type: application/json\r\nContent-Length: 80000\r\n\r\n" +
                         body[:1000])
            # Its headers are in once its room is counted (probing with bodies instead could
            # take the room first and have the held request refused).
            self.assertTrue(wait_until(lambda: metric(sdfclient.Client(s.url).metrics(),
                                                      "sdfd_buffered_bytes") == 80001, 10))
            got, data = raw_http(port, "POST", "/v1/meshes/demo/query", body,
                                 {"Content-Type": "application/json"})
            self.assertEqual((got, data["error"]["code"]), (429, "EBUSY"))
            self.assertIn("--max-buffered-bytes", data["error"]["message"])
            frame_points = np.zeros((6000, 3), np.float32)  # a 72 kB QUERY payload
            # A binary frame with no room is refused and its payload read and dropped: the
            # ERROR arrives, and the same connection goes on with the next frame.
            refused = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            self.addCleanup(refused.close)
            with self.assertRaises(sdfclient.SdfError) as e:
                refused.query("demo", frame_points)
            self.assertEqual((e.exception.status, e.exception.code), (429, "EBUSY"))
            self.assertIn("--max-buffered-bytes", e.exception.message)
            self.assertEqual(len(refused.query("demo", frame_points[:10])["distance"]), 10)
            # Pipelined behind a refused frame, the next frame is read from where it ends.
            busy, small = refused.query_many([("demo", frame_points), ("demo", frame_points[:7])])
            self.assertEqual((busy.status, busy.code), (429, "EBUSY"))
            self.assertEqual(len(small["distance"]), 7)
            self.assertEqual(metric(sdfclient.Client(s.url).metrics(), "sdfd_requests_total",
                                    'route="bin:query",status="429"'), 2)
            held.sendall(body[1000:])  # the held request completes and frees its room
            self.assertIn(b"200 OK", held.recv(4096))
            held.close()
            self.assertTrue(wait_until(lambda: raw_http(port, "POST", "/v1/meshes/demo/query",
                                                        body, {"Content-Type": "application/json"}
                                                        )[0] == 200, 10))
            # The refused connection's frame goes through once the room is back (the probe's
            # room is released just after its answer, so this may take a retry, as for any
            # client told EBUSY).
            def retried():
                try:
                    return len(refused.query("demo", frame_points)["distance"]) == 6000
                except sdfclient.SdfError as busy:
                    self.assertEqual(busy.code, "EBUSY")
                    return False
            self.assertTrue(wait_until(retried, 10))
            refused.close()
            # Every byte reserved is given back once nothing is held (no leak to block on):
            # a request's room is released when it completes, just after its answer is sent,
            # and a binary connection's input buffer when it closes.
            nothing_held = lambda: metric(sdfclient.Client(s.url).metrics(),  # noqa: E731
                                          "sdfd_buffered_bytes") == 0
            self.assertTrue(wait_until(nothing_held, 10))
            b = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            self.assertEqual(len(b.query("demo", frame_points)["distance"]), 6000)
            b.close()
            self.assertTrue(wait_until(nothing_held, 10))

    def test_binary_connections_share_the_budget(self):
        # Each binary connection holds a 64 KiB input buffer once it has read: two fit in
        # 150 kB, a third's first read does not. It gets an ERROR and is closed (there is no
        # frame yet to skip), and once another connection closes, room is back.
        with Server("--max-body-bytes", "100000", "--max-points", "10000",
                    "--max-buffered-bytes", "150000") as s:
            a = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            b = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            self.addCleanup(b.close)
            a.hello(), b.hello()
            third = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            self.addCleanup(third.close)
            with self.assertRaises(sdfclient.SdfError) as e:
                third.hello()
            self.assertEqual((e.exception.status, e.exception.code), (429, "EBUSY"))
            # On the wire: one ERROR with request id 0, then sdfd closes the connection.
            raw = socket.create_connection(("127.0.0.1", s.bin_port), timeout=10)
            self.addCleanup(raw.close)
            raw.sendall(sdfclient.BinaryClient.HEADER.pack(b"SDFP", 1, 0x01, 0, 7, 0))
            reply = b""
            while True:
                chunk = raw.recv(4096)
                if not chunk:
                    break
                reply += chunk
            _, _, kind, _, rid, length = sdfclient.BinaryClient.HEADER.unpack_from(reply)
            self.assertEqual((kind, rid, len(reply)), (0x7F, 0, 16 + length))
            a.close()
            self.assertTrue(wait_until(lambda: self._hello_on_a_new_connection(s.bin_port), 10))
            self.assertEqual(len(b.query("demo", np.zeros((5, 3), np.float32))["distance"]), 5)

    @staticmethod
    def _hello_on_a_new_connection(port):
        client = sdfclient.BinaryClient("127.0.0.1", port)
        try:
            client.hello()
            return True
        except sdfclient.SdfError as e:
            if e.code != "EBUSY":
                raise
            return False  # the closed connection's room is not back yet
        finally:
            client.close()

    def test_binary_connection_limits_and_logs(self):
        with Server("--max-per-ip", "2") as s:
            a = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            b = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            a.hello(), b.hello()
            c = socket.create_connection(("127.0.0.1", s.bin_port))
            c.settimeout(5)
            self.assertEqual(c.recv(16), b"", "a third connection from one address was kept")
            c.close()
            a.query("demo", np.zeros((3, 3)))
            a.close()
            self.assertTrue(wait_until(lambda: self._third_connects(s)))
            b.close()

            def binary_lines():
                return [e for e in s.logs if e.get("event") == "request" and e.get("proto") == "binary"]
            # The reply goes out before its log line is written: wait for the line.
            self.assertTrue(wait_until(lambda: any(
                e["method"] == "QUERY" and e["points"] == 3 and e["status"] == 200
                for e in binary_lines())), binary_lines())

    @staticmethod
    def _third_connects(s):
        try:
            c = sdfclient.BinaryClient("127.0.0.1", s.bin_port, timeout=2)
            c.hello()
            c.close()
            return True
        except (ConnectionError, OSError):
            return False


class Concurrency(unittest.TestCase):
    def test_64_clients_coalesce(self):
        with Server("--batch-window-us", "2000") as s:
            rng = np.random.default_rng(9)
            sets = [rng.uniform(-3, 3, (int(rng.integers(1, 50)), 3)).astype(np.float32)
                    for _ in range(64 * 8)]
            ref = sdfclient.Client(s.url)
            expected = [ref.query("demo", p, form="octet")["distance"] for p in sets]
            ref.close()
            errors = []

            def client(i):
                try:
                    binary = i % 2
                    c = (sdfclient.BinaryClient("127.0.0.1", s.bin_port) if binary
                         else sdfclient.Client(s.url))
                    for k in range(8):
                        j = 8 * i + k
                        r = c.query("demo", sets[j]) if binary else \
                            c.query("demo", sets[j], form=("npy", "octet", "json")[k % 3])
                        if r["distance"].tobytes() != expected[j].tobytes():
                            errors.append(f"client {i} request {k}: wrong answer")
                    c.close()
                except Exception as e:  # noqa: BLE001 - reported below
                    errors.append(f"client {i}: {e!r}")

            threads = [threading.Thread(target=client, args=(i,)) for i in range(64)]
            for t in threads:
                t.start()
            for t in threads:
                t.join(120)
            self.assertEqual(errors, [])
            text = sdfclient.Client(s.url).metrics()
            batches = metric(text, "sdfd_batch_requests_count")
            single = metric(text, "sdfd_batch_requests_bucket", 'le="1"')
            self.assertGreater(batches - single, 0, "no batch held more than one request")
            self.assertLess(batches, 64 * 8 * 2, "every request ran alone")
            print(f"\n  {int(batches)} batches for {64 * 8 * 2} requests; "
                  f"{int(batches - single)} held more than one", file=sys.stderr)

    def test_failed_batch_fails_only_its_culprit(self):
        # A filtered kernel of width ~1e17 (cap 1e17) displaces the samples of a point at
        # 9.9e17 beyond the +-1e18 the library accepts, while points near the demo mesh keep
        # theirs in place: with the same parameters, all three requests share one batch.
        with Server("--batch-window-us", "300000") as s:
            f = {"cap": 1e17}
            good = np.array([[3.35, 0, 0], [0.5, 0.2, 0.1]], np.float32)
            bad = np.array([[9.9e17, 0, 0]], np.float32)
            c = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
            alone = c.query("demo", good, mode="filtered", filter=f)["distance"]
            got = c.query_many([("demo", good), ("demo", bad), ("demo", good)],
                               mode="filtered", filter=f)
            c.close()
            self.assertIsInstance(got[1], sdfclient.SdfError)
            self.assertEqual((got[1].status, got[1].code), (422, "ENONFINITE"))
            self.assertIn("make it narrower", got[1].message)  # the library's own reason
            for k in (0, 2):
                self.assertNotIsInstance(got[k], sdfclient.SdfError, got[k])
                self.assertEqual(got[k]["distance"].tobytes(), alone.tobytes())
            text = sdfclient.Client(s.url).metrics()
            shared = metric(text, "sdfd_batch_requests_count") - \
                metric(text, "sdfd_batch_requests_bucket", 'le="1"')
            self.assertGreater(shared, 0, "the three requests did not share a batch")
            # Over HTTP, the refusal carries the same reason.
            status, data = raw_http(s.ports["http"], "POST", "/v1/meshes/demo/query",
                                    json.dumps({"points": bad.tolist(), "mode": "filtered",
                                                "filter": f}).encode(),
                                    {"Content-Type": "application/json"})
            self.assertEqual(status, 422)
            self.assertIn("make it narrower", data["error"]["message"])


BIN_RESULT = 0x83


def binary_drain_logged(server):
    return any(e.get("event") == "shutdown" and e.get("message", "").startswith("binary:")
               for e in server.logs)


class Shutdown(unittest.TestCase):
    def test_sigterm_answers_everything_in_flight(self):
        s = Server()
        big = np.random.default_rng(3).uniform(-3, 3, (200000, 3)).astype(np.float32)
        results, errors = [], []

        def client(i):
            try:
                c = (sdfclient.BinaryClient("127.0.0.1", s.bin_port) if i % 2
                     else sdfclient.Client(s.url))
                results.append(len(c.query("demo", big)["distance"]))
            except Exception as e:  # noqa: BLE001
                errors.append(repr(e))

        watcher = sdfclient.Client(s.url)  # a kept-alive connection, open before the drain
        threads = [threading.Thread(target=client, args=(i,)) for i in range(8)]
        for t in threads:
            t.start()
        # Wait until all 8 are in flight (the batcher is busy with the first ones).
        self.assertTrue(wait_until(lambda: metric(watcher.metrics(), "sdfd_points_total")
                                   >= 8 * 200000, 30))
        s.proc.send_signal(signal.SIGTERM)
        self.assertTrue(wait_until(lambda: any(e.get("event") == "shutdown" for e in s.logs), 10))
        status, _ = self._readyz(watcher)
        self.assertEqual(status, 503, "/readyz on an open connection while draining")
        self.assertTrue(wait_until(lambda: binary_drain_logged(s), 10))
        with self.assertRaises(ConnectionRefusedError):  # both sockets are shut: refused at once
            socket.create_connection(("127.0.0.1", s.bin_port), timeout=2)
        with self.assertRaises(ConnectionRefusedError):
            socket.create_connection(("127.0.0.1", s.ports["http"]), timeout=2)
        for t in threads:
            t.join(120)
        self.assertEqual(errors, [])
        self.assertEqual(results, [200000] * 8)
        self.assertEqual(s.stop(), 0)
        events = [e.get("event") for e in s.logs]
        self.assertIn("shutdown", events)
        self.assertEqual(events[-1], "stopped")

    def test_sigterm_sheds_binary_clients(self):
        """A draining sdfd sheds its binary clients so that they reconnect elsewhere: a
        pipeline's queries sent before SIGTERM are each answered bit for bit or lost with the
        connection (never a 503), idle connections end at once, new connects are refused, and
        the server exits 0 having logged the drain."""
        n, queries = 20000, 32
        # One query a batch, so the replies come one by one and the signal lands mid-pipeline.
        s = Server("--batch-max-points", str(n), "--drain-seconds", "60")
        rng = np.random.default_rng(5)
        frames = {rid: bin_query(rid, rng.uniform(-3, 3, (n, 3)).astype(np.float32))
                  for rid in range(1, queries + 1)}
        ref = {}  # each query's reply payload, from a connection of its own before the drain
        with socket.create_connection(("127.0.0.1", s.bin_port), timeout=60) as c:
            for rid, frame in frames.items():
                c.sendall(frame)
                type_, got, payload = recv_frame(c)
                self.assertEqual((type_, got), (BIN_RESULT, rid), payload[:200])
                ref[rid] = payload
        hello = socket.create_connection(("127.0.0.1", s.bin_port), timeout=60)
        hello.sendall(BIN_HEADER.pack(b"SDFP", 1, 1, 0, 99, 0))  # spoke once, now between frames
        self.assertEqual(recv_frame(hello)[:2], (0x81, 99))
        silent = socket.create_connection(("127.0.0.1", s.bin_port), timeout=60)  # never speaks
        half = socket.create_connection(("127.0.0.1", s.bin_port), timeout=60)
        half.sendall(frames[1][:100])  # stops mid-frame
        pipe = socket.create_connection(("127.0.0.1", s.bin_port), timeout=60)
        pipe.sendall(b"".join(frames.values()))
        first = recv_frame(pipe)  # the pipeline is under way
        s.proc.send_signal(signal.SIGTERM)
        signalled = time.time()
        for name, sock in (("hello", hello), ("silent", silent), ("half", half)):
            sock.settimeout(5)
            self.assertEqual(sock.recv(100), b"", f"the {name} connection got bytes, not EOF")
            sock.close()
        idle_closed = time.time() - signalled
        still_draining = s.proc.poll() is None
        self.assertTrue(wait_until(lambda: binary_drain_logged(s), 10))
        with self.assertRaises(ConnectionRefusedError):
            socket.create_connection(("127.0.0.1", s.bin_port), timeout=2)
        answered = [first]
        while True:
            try:
                answered.append(recv_frame(pipe))
            except (ConnectionError, OSError):
                break  # the connection ended: the rest is the client's to send elsewhere
        pipe_closed = time.time() - signalled
        pipe.close()
        lost = queries - len(answered)
        print(f"\n  binary drain: idle connections closed {idle_closed * 1e3:.0f} ms after "
              f"SIGTERM, the pipeline's {pipe_closed * 1e3:.0f} ms after; of its {queries} "
              f"queries {len(answered)} answered, {lost} lost with the connection",
              file=sys.stderr)
        for type_, rid, payload in answered:
            self.assertEqual(type_, BIN_RESULT, f"query {rid}: {payload[:200]!r}")
            self.assertEqual(payload, ref[rid], f"query {rid}: not the reference's bytes")
        self.assertEqual(len({rid for _, rid, _ in answered}), len(answered), "a reply twice")
        self.assertGreater(len(answered), 1, "no reply after the signal: not mid-pipeline")
        self.assertLess(idle_closed, 2.0, "idle connections not closed at once")
        self.assertTrue(still_draining, "idle connections ended only with the process")
        self.assertEqual(s.stop(), 0)
        self.assertTrue(binary_drain_logged(s))
        self.assertEqual([e.get("event") for e in s.logs][-1], "stopped")

    def test_loading_answers_503_not_404(self):
        """A replica listens before its meshes are loaded (so /readyz can say so): until then
        a query of a mesh it will serve is 503 EUNAVAILABLE on both protocols, never 404, and
        a load balancer retries it elsewhere."""
        import tempfile
        with tempfile.TemporaryDirectory() as d:
            src = os.path.abspath(os.path.join(os.environ.get("SDF_TEST_DATA", "tests/data"),
                                               "refined_elephant.off"))
            for i in range(8):  # ~2 s of loading in a release build, longer in the others
                os.symlink(src, os.path.join(d, f"m{i}.off"))
            s = Server("--mesh-dir", d, wait_ready=False)
            try:
                self.assertTrue(wait_until(lambda: "http" in s.ports and "binary" in s.ports, 30))
                port = int(s.url.rsplit(":", 1)[1])
                body = json.dumps({"points": [[0, 0, 0]]}).encode()
                b = sdfclient.BinaryClient("127.0.0.1", s.bin_port)
                seen = []
                while raw_http(port, "GET", "/readyz")[0] == 503:
                    status, data = raw_http(port, "POST", "/v1/meshes/m7/query", body, BadInput.JSON)
                    try:
                        b.query("m7", np.zeros((1, 3), np.float32))
                        binary = None
                    except sdfclient.SdfError as e:
                        binary = e.code
                    if raw_http(port, "GET", "/readyz")[0] != 503:
                        break  # ready meanwhile: either answer is right
                    seen.append((status, data["error"]["code"] if status != 200 else None, binary))
                self.assertTrue(seen, "the server was never seen loading")
                self.assertEqual(set(seen), {(503, "EUNAVAILABLE", "EUNAVAILABLE")})
                d0 = b.query("m7", np.zeros((1, 3), np.float32))["distance"]
                self.assertTrue(np.isfinite(d0).all())
                status, data = raw_http(port, "POST", "/v1/meshes/m7/query", body, BadInput.JSON)
                self.assertEqual(status, 200, data)
                b.close()
            finally:
                s.stop()

    @staticmethod
    def _readyz(client):
        try:
            client._request("GET", "/readyz")
            return 200, None
        except sdfclient.SdfError as e:
            return e.status, e


if __name__ == "__main__":
    unittest.main(verbosity=2)
