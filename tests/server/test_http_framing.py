"""Where an HTTP request ends (RFC 9112 section 6.3), over raw sockets so that the test, not a
client library, writes the header fields. A request two parsers could frame two ways is
answered 400 ESYNTAX from its headers and its connection closed, so that no byte after the
headers is taken for a request (server/httpframing.c):
  - Content-Length twice with different values (an upload among them: nothing is stored);
  - Content-Length with Transfer-Encoding, in either order;
  - white space between a field name and its colon ("Transfer-Encoding : chunked", a tab).
Requests smuggled behind each are never answered. What libmicrohttpd 0.9.75 refuses itself is
checked too: a Content-Length that is not one decimal number (400, its HTML page) or past 64
bits (413), connection closed. Two Content-Length fields with the same value are one length
and answered; Transfer-Encoding alone stays 411 ELENGTH. The server answers afterwards."""
import json
import os
import socket
import struct
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from harness import Server  # noqa: E402

POINT = struct.pack("<3f", 0.0, 0.0, 0.0)  # 12 bytes, one query point
QUERY = (b"POST /v1/meshes/demo/query HTTP/1.1\r\nHost: x\r\n"
         b"Content-Type: application/octet-stream\r\n")
SMUGGLED = b"GET /v1/meshes HTTP/1.1\r\nHost: x\r\n\r\n"


def chunked(data):
    return b"%x\r\n" % len(data) + data + b"\r\n0\r\n\r\n"


def exchange(port, raw, timeout=10):
    """Send `raw` on a new connection and read until the server closes it: (the bytes
    received, whether it closed within `timeout`)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(raw)
        got = b""
        try:
            while True:
                d = s.recv(65536)
                if not d:
                    return got, True
                got += d
        except socket.timeout:
            return got, False


def responses(data):
    """The responses in `data`, each (status, headers dict in lower case, body)."""
    out = []
    while data.startswith(b"HTTP/1.1 "):
        head, _, rest = data.partition(b"\r\n\r\n")
        lines = head.split(b"\r\n")
        headers = dict(line.decode().lower().split(": ", 1) for line in lines[1:])
        n = int(headers.get("content-length", 0))
        out.append((int(lines[0].split()[1]), headers, rest[:n]))
        data = rest[n:]
    return out


class Framing(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server()
        cls.port = cls.server.ports["http"]

    @classmethod
    def tearDownClass(cls):
        code = cls.server.stop()  # raises on a sanitizer report
        assert code == 0, f"sdfd exited with {code}"

    def refused(self, raw, says):
        """`raw` is answered 400 ESYNTAX naming `says`, alone, and the connection closed."""
        data, closed = exchange(self.port, raw)
        self.assertTrue(closed, "the connection was left open")
        rs = responses(data)
        self.assertEqual(len(rs), 1, data)  # nothing behind it was answered
        status, headers, body = rs[0]
        self.assertEqual(status, 400, data)
        self.assertEqual(headers.get("connection"), "close")
        err = json.loads(body)["error"]
        self.assertEqual(err["code"], "ESYNTAX")
        self.assertIn(says, err["message"])

    def answered(self, raw, status):
        data, _ = exchange(self.port, raw, timeout=2)
        rs = responses(data)
        self.assertGreaterEqual(len(rs), 1, data)
        self.assertEqual(rs[0][0], status, data)
        return rs[0]

    def test_two_content_lengths(self):
        for a, b in ((12, 24), (24, 12), (12, 0)):
            body = (POINT * 2)[:max(a, b)]
            self.refused(QUERY + b"Content-Length: %d\r\nContent-Length: %d\r\n\r\n" % (a, b)
                         + body + SMUGGLED, "Content-Length is given twice, as %d and as %d"
                         % (a, b))
        # an upload: refused, and nothing stored
        mesh = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
        self.refused(b"PUT /v1/meshes/twice HTTP/1.1\r\nHost: x\r\nContent-Length: %d\r\n"
                     b"Content-Length: %d\r\n\r\n" % (len(mesh), len(mesh) + 5) + mesh
                     + b"v 1 1 1", "Content-Length is given twice")
        self.answered(b"GET /v1/meshes/twice HTTP/1.1\r\nHost: x\r\n\r\n", 404)

    def test_same_content_length_twice_is_one(self):
        _, headers, body = self.answered(
            QUERY + b"Content-Length: 12\r\ncontent-length: 12\r\n\r\n" + POINT, 200)
        self.assertEqual(headers["x-sdf-count"], "1")
        self.assertEqual(len(body), 4)

    def test_content_length_and_transfer_encoding(self):
        for fields in (b"Content-Length: 12\r\nTransfer-Encoding: chunked\r\n",
                       b"Transfer-Encoding: chunked\r\nContent-Length: 12\r\n",
                       b"Content-Length: 12\r\nTransfer-Encoding: gzip, chunked\r\n"):
            self.refused(QUERY + fields + b"\r\n" + chunked(POINT) + SMUGGLED,
                         "both Content-Length and Transfer-Encoding")
        # on a route without a body too: the framing is read before the route
        self.refused(b"GET /healthz HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n"
                     b"Transfer-Encoding: chunked\r\n\r\n0\r\n\r\n" + SMUGGLED,
                     "both Content-Length and Transfer-Encoding")

    def test_white_space_before_the_colon(self):
        self.refused(QUERY + b"Transfer-Encoding : chunked\r\n\r\n" + chunked(POINT) + SMUGGLED,
                     "'Transfer-Encoding ' and its colon")
        self.refused(QUERY + b"Content-Length\t: 12\r\n\r\n" + POINT + SMUGGLED,
                     "'Content-Length?' and its colon")
        self.refused(b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Anything : 1\r\n\r\n",
                     "'X-Anything ' and its colon")

    def test_what_libmicrohttpd_refuses_itself(self):
        for value, status in ((b"12, 24", 400), (b"12,12", 400), (b"-1", 400), (b"+12", 400),
                              (b"abc", 400), (b"99999999999999999999999", 413)):
            data, closed = exchange(self.port, QUERY + b"Content-Length: " + value + b"\r\n\r\n"
                                    + POINT + SMUGGLED)
            self.assertTrue(closed, value)
            self.assertTrue(data.startswith(b"HTTP/1.1 %d " % status), (value, data[:80]))
            self.assertIn(b"Content-Length", data, value)  # its page names the field
            self.assertNotIn(b'"meshes"', data, value)  # the smuggled GET was not answered

    def test_transfer_encoding_alone_needs_a_length(self):
        data, closed = exchange(self.port, QUERY + b"Transfer-Encoding: chunked\r\n\r\n"
                                + chunked(POINT) + SMUGGLED)
        self.assertTrue(closed)
        rs = responses(data)
        self.assertEqual([r[0] for r in rs], [411], data)
        self.assertEqual(json.loads(rs[0][2])["error"]["code"], "ELENGTH")

    def test_server_answers_afterwards(self):
        self.refused(QUERY + b"Content-Length: 12\r\nContent-Length: 13\r\n\r\n" + POINT,
                     "given twice")
        _, headers, _ = self.answered(QUERY + b"Content-Length: 12\r\n\r\n" + POINT, 200)
        self.assertEqual(headers["x-sdf-count"], "1")


if __name__ == "__main__":
    unittest.main(verbosity=2)
