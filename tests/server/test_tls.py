"""sdfd over TLS (--tls-cert, --tls-key, --bin-tls) with certificates made here by certtool
(gnutls-bin, a declared dependency in .ci/deps): curl, gnutls-cli and the Python clients
verify the server against a test CA; a client with another CA, a TLS 1.1 client and a
plain-HTTP request are refused; a handshake that stops halfway holds nothing past
--timeout; SIGHUP swaps the certificate for new connections while open ones go on; the
answers over TLS are the plain protocols' bits; bad files stop sdfd before it listens."""
import http.client
import json
import os
import shutil
import signal
import socket
import ssl
import subprocess
import sys
import tempfile
import time
import unittest
from contextlib import closing

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "clients", "python"))
import sdfclient  # noqa: E402
from harness import SDFD, Server, same_bits, wait_until  # noqa: E402

TIMEOUT = 2  # the servers' --timeout: a stalled handshake is cut after it


def certtool(*args):
    subprocess.run(["certtool", *args], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)


def make_ca(d, name):
    """A self-signed CA in d: (certificate path, key path)."""
    key, cert, tmpl = (os.path.join(d, f"{name}.{e}") for e in ("key", "pem", "tmpl"))
    with open(tmpl, "w") as f:
        f.write(f'cn = "{name}"\nca\ncert_signing_key\nexpiration_days = 2\n')
    certtool("--generate-privkey", "--key-type=ecdsa", "--outfile", key)
    certtool("--generate-self-signed", "--load-privkey", key, "--template", tmpl,
             "--outfile", cert)
    return cert, key


def make_server_cert(d, name, ca, serial):
    """A certificate for 127.0.0.1 and localhost signed by ca, with this serial."""
    key, cert, tmpl = (os.path.join(d, f"{name}.{e}") for e in ("key", "pem", "tmpl"))
    with open(tmpl, "w") as f:
        f.write('cn = "localhost"\ndns_name = "localhost"\nip_address = "127.0.0.1"\n'
                f"tls_www_server\nsigning_key\nencryption_key\nexpiration_days = 2\n"
                f"serial = {serial}\n")
    certtool("--generate-privkey", "--key-type=ecdsa", "--outfile", key)
    certtool("--generate-certificate", "--load-privkey", key, "--load-ca-certificate", ca[0],
             "--load-ca-privkey", ca[1], "--template", tmpl, "--outfile", cert)
    return cert, key


def serial_of(sock):
    """The serial (as int) of the certificate the TLS socket's server presented."""
    return int(sock.getpeercert()["serialNumber"], 16)


def bits(a):
    return np.ascontiguousarray(a).tobytes()


def tls_context(cafile):
    return ssl.create_default_context(cafile=cafile)


class Certificates:
    """A temp dir with the CA, another CA, two server certificates (serials 0x1001, 0x2002)
    and the files sdfd serves (a copy of the first, which tests may overwrite)."""

    def __init__(self):
        self.dir = tempfile.mkdtemp(prefix="sdfd-tls-")
        self.ca = make_ca(self.dir, "ca")
        self.other_ca = make_ca(self.dir, "other-ca")
        self.first = make_server_cert(self.dir, "first", self.ca, 0x1001)
        self.second = make_server_cert(self.dir, "second", self.ca, 0x2002)
        self.cert = os.path.join(self.dir, "served.pem")
        self.key = os.path.join(self.dir, "served.key")
        self.serve(self.first)

    def serve(self, pair):
        """Replace the served files (each by a rename, as a deploy would)."""
        for src, dst in zip(pair, (self.cert, self.key)):
            shutil.copyfile(src, dst + ".new")
            os.replace(dst + ".new", dst)

    def remove(self):
        shutil.rmtree(self.dir, ignore_errors=True)


def https_url(server):
    return f"https://127.0.0.1:{server.ports['http']}"


def curl(*args):
    return subprocess.run(["curl", "-sS", "--max-time", "20", *args], capture_output=True)


def log_events(server, event):
    return [e for e in server.logs if e.get("event") == event]


class Tls(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.certs = Certificates()
        cls.server = Server("--tls-cert", cls.certs.cert, "--tls-key", cls.certs.key,
                            "--bin-tls", "--timeout", str(TIMEOUT))
        cls.plain = Server("--timeout", str(TIMEOUT))
        cls.points = np.random.default_rng(3).uniform(-3, 3, (2000, 3)).astype(np.float32)

    @classmethod
    def tearDownClass(cls):
        codes = (cls.server.stop(), cls.plain.stop())
        cls.certs.remove()
        assert codes == (0, 0), codes

    def https(self, cafile=None):
        return sdfclient.Client(https_url(self.server), cafile=cafile or self.certs.ca[0])

    def binary(self, cafile=None):
        return sdfclient.BinaryClient("127.0.0.1", self.server.bin_port, tls=True,
                                      cafile=cafile or self.certs.ca[0])

    def test_curl_query(self):
        body = json.dumps({"points": self.points[:50].tolist()})
        r = curl("--cacert", self.certs.ca[0], "-H", "Content-Type: application/json",
                 "--data-binary", body, https_url(self.server) + "/v1/meshes/demo/query")
        self.assertEqual(r.returncode, 0, r.stderr)
        got = np.array(json.loads(r.stdout)["distance"], np.float32)
        with closing(sdfclient.Client(self.plain.url)) as c:
            want = c.query("demo", self.points[:50])["distance"]
        self.assertTrue(same_bits(got, want))

    def test_same_answers_as_plain(self):
        """HTTPS and binary-over-TLS give the plain protocols' float32 bits, every mode."""
        for mode in ("signed", "gradient", "closest"):
            with closing(self.https()) as h, closing(sdfclient.Client(self.plain.url)) as p:
                a, b = h.query("demo", self.points, mode=mode), p.query("demo", self.points,
                                                                         mode=mode)
            self.assertEqual(set(a), set(b))
            for k in a:
                self.assertTrue(bits(a[k]) == bits(b[k]), k)
            t, u = self.binary(), sdfclient.BinaryClient("127.0.0.1", self.plain.bin_port)
            try:
                c, d = t.query("demo", self.points, mode=mode), u.query("demo", self.points,
                                                                         mode=mode)
                many = t.query_many([("demo", self.points[i::7]) for i in range(7)], window=7)
            finally:
                t.close(), u.close()
            for k in c:
                self.assertTrue(bits(c[k]) == bits(d[k]), k)
                self.assertTrue(bits(c[k]) == bits(a[k]), k)
            for i, r in enumerate(many):
                self.assertTrue(same_bits(r["distance"], d["distance"][i::7]))

    def test_large_replies_cross_many_records(self):
        """A reply much larger than one TLS record (16 KiB), pipelined with others."""
        big = np.random.default_rng(9).uniform(-3, 3, (300000, 3)).astype(np.float32)
        t = self.binary()
        try:
            rs = t.query_many([("demo", big)] * 3, window=3)
        finally:
            t.close()
        with closing(sdfclient.Client(self.plain.url)) as p:
            want = p.query("demo", big)["distance"]
        for r in rs:
            self.assertTrue(same_bits(r["distance"], want))

    def test_wrong_ca_fails_in_the_client(self):
        r = curl("--cacert", self.certs.other_ca[0], https_url(self.server) + "/healthz")
        self.assertEqual(r.returncode, 60, r.stderr)  # peer certificate cannot be authenticated
        c = self.https(self.certs.other_ca[0])
        with self.assertRaises(ssl.SSLCertVerificationError):
            c.health()
        c.close()
        with self.assertRaises(ssl.SSLCertVerificationError):
            self.binary(self.certs.other_ca[0])
        with closing(self.https()) as c:  # the server goes on
            self.assertEqual(c.health()["status"], "ok")

    def test_plain_http_to_the_tls_port_is_refused(self):
        with socket.create_connection(("127.0.0.1", self.server.ports["http"]), 10) as s:
            s.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
            reply = b""
            try:
                while chunk := s.recv(4096):
                    reply += chunk
            except ConnectionResetError:
                pass
        self.assertNotIn(b"HTTP/1.", reply)  # closed, not answered in clear text
        with socket.create_connection(("127.0.0.1", self.server.bin_port), 10) as s:
            s.sendall(b"SDFP\x01\x01\x00\x00\x01\x00\x00\x00\x00\x00\x00\x00")  # a plain HELLO
            s.settimeout(TIMEOUT + 10)
            try:
                reply = s.recv(4096)
            except ConnectionResetError:
                reply = b""
        self.assertNotIn(b"SDFP", reply)
        with closing(self.https()) as c:
            self.assertEqual(c.health()["status"], "ok")
        b = self.binary()
        self.assertEqual(b.hello()["version"], 1)
        b.close()

    def gnutls_cli(self, port, versions):
        return subprocess.run(
            ["gnutls-cli", f"--x509cafile={self.certs.ca[0]}", f"--port={port}",
             f"--priority=NORMAL:-VERS-ALL:{versions}", "127.0.0.1"],
            stdin=subprocess.DEVNULL, capture_output=True, timeout=30)

    def test_tls_1_1_refused_1_2_accepted(self):
        for port in (self.server.ports["http"], self.server.bin_port):
            old = self.gnutls_cli(port, "+VERS-TLS1.1")
            self.assertNotEqual(old.returncode, 0)
            self.assertNotIn(b"Handshake was completed", old.stdout + old.stderr)
            for ok in ("+VERS-TLS1.2", "+VERS-TLS1.3"):
                r = self.gnutls_cli(port, ok)
                self.assertEqual(r.returncode, 0, (port, ok, r.stderr[-500:]))
                self.assertIn(b"Handshake was completed", r.stdout + r.stderr)

    def test_truncated_handshake_holds_nothing(self):
        """Connections that send half a ClientHello and hang: other clients are served at
        once meanwhile, and each hanging one is closed once --timeout has passed."""
        hello = client_hello_bytes()
        hung = []
        for port in [self.server.ports["http"]] * 6 + [self.server.bin_port] * 6:
            s = socket.create_connection(("127.0.0.1", port), 10)
            s.sendall(hello[:len(hello) // 2])
            hung.append(s)
        start = time.monotonic()
        with closing(self.https()) as c:
            self.assertEqual(c.query("demo", self.points[:10])["distance"].shape, (10,))
        b = self.binary()
        self.assertEqual(b.query("demo", self.points[:10])["distance"].shape, (10,))
        b.close()
        self.assertLess(time.monotonic() - start, TIMEOUT)  # not after the stalled ones' cut
        for s in hung:  # closed by the server (perhaps after a TLS alert): the end of stream
            s.settimeout(TIMEOUT + 10)
            try:
                while s.recv(4096):
                    pass
            except ConnectionResetError:
                pass
            s.close()
        waited = time.monotonic() - start
        self.assertGreater(waited, TIMEOUT - 1)
        self.assertLess(waited, TIMEOUT + 8)


def client_hello_bytes():
    """A real TLS ClientHello, as Python's ssl writes it (captured from a socket pair)."""
    a, b = socket.socketpair()
    ctx = ssl.create_default_context()
    out = ssl.MemoryBIO()
    obj = ctx.wrap_bio(ssl.MemoryBIO(), out, server_hostname="localhost")
    try:
        obj.do_handshake()
    except ssl.SSLWantReadError:
        pass
    a.close(), b.close()
    return out.read()


class Reload(unittest.TestCase):
    """SIGHUP: new connections get the new certificate, open ones go on with theirs; a bad
    file leaves the certificate in use."""

    def setUp(self):
        self.certs = Certificates()
        self.server = Server("--tls-cert", self.certs.cert, "--tls-key", self.certs.key,
                             "--bin-tls")
        self.ctx = tls_context(self.certs.ca[0])

    def tearDown(self):
        self.assertEqual(self.server.stop(), 0)
        self.certs.remove()

    def hup(self, event_level):
        n = len([e for e in log_events(self.server, "tls_reload")])
        self.server.proc.send_signal(signal.SIGHUP)
        self.assertTrue(wait_until(lambda: len(log_events(self.server, "tls_reload")) > n))
        self.assertEqual(log_events(self.server, "tls_reload")[-1]["level"], event_level)

    def https_conn(self):
        c = http.client.HTTPSConnection("127.0.0.1", self.server.ports["http"], timeout=20,
                                        context=self.ctx)
        c.request("GET", "/healthz")
        self.assertEqual(c.getresponse().read(), b'{"status":"ok"}')
        return c

    def binary(self):
        return sdfclient.BinaryClient("127.0.0.1", self.server.bin_port, tls=True,
                                      cafile=self.certs.ca[0])

    def test_sighup_swaps_the_certificate(self):
        old_http, old_bin = self.https_conn(), self.binary()
        self.assertEqual(serial_of(old_http.sock), 0x1001)
        self.assertEqual(serial_of(old_bin.sock), 0x1001)
        self.certs.serve(self.certs.second)
        self.hup("info")
        new_http, new_bin = self.https_conn(), self.binary()
        self.assertEqual(serial_of(new_http.sock), 0x2002)
        self.assertEqual(serial_of(new_bin.sock), 0x2002)
        # The kept-alive connections were not dropped: the same sockets answer.
        sock = old_http.sock
        old_http.request("GET", "/v1/meshes")
        self.assertEqual(json.loads(old_http.getresponse().read())["meshes"][0]["name"], "demo")
        self.assertIs(old_http.sock, sock)
        self.assertEqual(old_bin.hello()["version"], 1)
        self.assertEqual(old_bin.query("demo", np.zeros((4, 3)))["distance"].shape, (4,))
        for c in (old_http, old_bin, new_http, new_bin):
            c.close()
        # A third certificate after the first one's connections have closed (it is freed).
        self.certs.serve(self.certs.first)
        self.hup("info")
        with closing(self.binary()) as b:
            self.assertEqual(serial_of(b.sock), 0x1001)

    def test_bad_files_at_reload_keep_the_certificate(self):
        bad = os.path.join(self.certs.dir, "junk.pem")
        with open(bad, "w") as f:
            f.write("-----BEGIN CERTIFICATE-----\nnot base64 at all\n-----END CERTIFICATE-----\n")
        cases = [(bad, self.certs.key),                      # not a certificate
                 (self.certs.second[0], self.certs.first[1]),  # the key is another's
                 (os.path.join(self.certs.dir, "missing.pem"), self.certs.key)]
        for cert, key in cases:
            self.certs.serve(self.certs.first)
            if os.path.exists(cert):
                shutil.copyfile(cert, self.certs.cert)
            else:
                os.remove(self.certs.cert)
            if key != self.certs.key:
                shutil.copyfile(key, self.certs.key)
            self.hup("error")
            self.assertIn("the certificate in use stays",
                          log_events(self.server, "tls_reload")[-1]["message"])
            c = self.https_conn()
            self.assertEqual(serial_of(c.sock), 0x1001)
            c.close()
            with closing(self.binary()) as b:
                self.assertEqual(serial_of(b.sock), 0x1001)


class StartErrors(unittest.TestCase):
    """Bad TLS files or flags: a message and exit status 2 before anything listens."""

    @classmethod
    def setUpClass(cls):
        cls.certs = Certificates()

    @classmethod
    def tearDownClass(cls):
        cls.certs.remove()

    def start(self, *args):
        p = subprocess.run([SDFD, "--http", "127.0.0.1:0", "--bin", "127.0.0.1:0", *args],
                           capture_output=True, timeout=60)
        self.assertNotIn(b'"listening"', p.stderr)
        return p.returncode, p.stderr.decode()

    def test_bad_files(self):
        d = self.certs.dir
        junk = os.path.join(d, "junk")
        with open(junk, "w") as f:
            f.write("hello\n")
        empty = os.path.join(d, "empty")
        open(empty, "w").close()
        cases = [
            ((os.path.join(d, "nope.pem"), self.certs.first[1]), "No such file"),
            ((self.certs.first[0], os.path.join(d, "nope.key")), "No such file"),
            ((junk, self.certs.first[1]), "--tls-cert"),
            ((empty, self.certs.first[1]), "1 to 1048576 bytes"),
            ((self.certs.first[0], junk), "--tls-key"),
            ((self.certs.first[0], self.certs.second[1]), "is not the key of the certificate"),
            ((d, self.certs.first[1]), "not a regular file"),
        ]
        for (cert, key), why in cases:
            code, err = self.start("--tls-cert", cert, "--tls-key", key)
            self.assertEqual(code, 2, err)
            self.assertIn(why, err)

    def test_flags_that_do_not_go_together(self):
        for args, why in [(["--tls-cert", self.certs.cert], "give both or neither"),
                          (["--tls-key", self.certs.key], "give both or neither"),
                          (["--bin-tls"], "--bin-tls needs --tls-cert")]:
            code, err = self.start(*args)
            self.assertEqual(code, 2, err)
            self.assertIn(why, err)

    def test_environment(self):
        """SDFD_TLS_CERT, SDFD_TLS_KEY and SDFD_BIN_TLS do what the flags do."""
        env = dict(os.environ, SDFD_TLS_CERT=self.certs.first[0],
                   SDFD_TLS_KEY=self.certs.first[1], SDFD_BIN_TLS="1")
        old = os.environ.copy()
        os.environ.update(env)
        try:
            server = Server()
        finally:
            os.environ.clear()
            os.environ.update(old)
        try:
            with closing(sdfclient.BinaryClient("127.0.0.1", server.bin_port, tls=True,
                                                cafile=self.certs.ca[0])) as b:
                self.assertEqual(serial_of(b.sock), 0x1001)
        finally:
            self.assertEqual(server.stop(), 0)

    def test_sighup_without_tls_is_ignored(self):
        with Server() as s:
            s.proc.send_signal(signal.SIGHUP)
            self.assertTrue(wait_until(lambda: log_events(s, "tls_reload")))
            with closing(sdfclient.Client(s.url)) as c:
                self.assertEqual(c.health()["status"], "ok")


if __name__ == "__main__":
    unittest.main(verbosity=2)
