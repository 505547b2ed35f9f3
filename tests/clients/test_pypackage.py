"""clients/python as an installed package: a virtual environment (with the system's site
packages, for Debian's numpy) in a temporary directory, `pip install --no-build-isolation
--no-index` of a copy of clients/python into it (offline: no package index), then, in fresh
processes whose working directory is outside the source tree, checks that `import sdfclient`
finds the installed copy (in the venv's site-packages, byte-equal to the source, with py.typed
and the version pyproject.toml reads from the package); that it queries a real sdfd over HTTP
and the binary protocol with answers bit-equal to the server's plain JSON answers; that the
examples in clients/python/README.md run; and that pyflakes and mypy --strict pass on the
package, while mypy, run as a user's project would, sees the installed type hints: it accepts
the README's examples and rejects calls that break them. BinaryClient's re-sending is
checked through a loopback proxy (CutProxy) that cuts connections mid-reply or hands them
to a draining server.

The source is copied first because pip builds in place and would leave build/ and egg-info
in the source tree."""
import ast
import json
import os
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import urllib.request

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.normpath(os.path.join(HERE, "..", "..", "clients", "python"))
sys.path.insert(0, os.path.join(HERE, "..", "server"))
from harness import Server, metric, recv_exact, wait_until  # noqa: E402


def run(args, cwd, timeout=240, expect=0):
    """Run a command with no PYTHONPATH (so nothing but the venv can supply sdfclient);
    its stdout, after checking its exit code."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    p = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    if p.returncode != expect:
        raise AssertionError(f"{args[:4]} exited {p.returncode}, expected {expect}:\n"
                             f"{p.stdout[-4000:]}\n{p.stderr[-4000:]}")
    return p.stdout


def json_query(url, name, points, mode):
    """The server's own JSON answer to a mesh query, as float32 arrays."""
    body = json.dumps({"points": points.tolist(), "mode": mode}).encode()
    req = urllib.request.Request(f"{url}/v1/meshes/{name}/query", body,
                                 {"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=60) as r:
        ref = json.load(r)
    out = {"distance": np.asarray(ref["distance"], np.float32)}
    if "gradient" in ref:
        out["gradient"] = np.asarray(ref["gradient"], np.float32).reshape(-1, 3)
    return out


class CutProxy:
    """A loopback proxy for the binary protocol. Connection k follows plan[k] (the last entry
    for the rest), a (how, port) pair: "pass" relays both ways to `port`; "cut" relays the
    client's bytes and the server's frames up to the first RESULT, of which it relays half
    and then closes both ends, so that the connection dies in the middle of a reply;
    "cut-sent" (for TLS, whose frames it cannot read) relays both ways until the client has
    sent CUT_SENT bytes, then closes both ends, so that the request dies before its reply.
    With `hold`, "cut" relays that half RESULT only once the client has sent `hold` bytes on
    the connection, so that every pipelined request is out before the cut, however slowly
    the client writes (a sanitizer build)."""

    CUT_SENT = 3000  # more than a TLS handshake and AUTH or HELLO, less than 300 points

    def __init__(self, plan, hold=0):
        self.plan, self.connections, self.hold, self.sent = plan, 0, hold, {}
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self):
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            how, port = self.plan[min(self.connections, len(self.plan) - 1)]
            self.connections += 1
            upstream = socket.create_connection(("127.0.0.1", port))
            k = self.connections
            self.sent[k] = 0
            threading.Thread(target=self._up, args=(client, upstream, how, k),
                             daemon=True).start()
            threading.Thread(target=self._down, args=(client, upstream, how, k),
                             daemon=True).start()

    @staticmethod
    def _end(*socks):
        for s in socks:
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()

    def _up(self, client, upstream, how, k):
        try:
            while True:
                data = client.recv(1 << 16)
                if not data:
                    break
                upstream.sendall(data)
                self.sent[k] += len(data)
                if how == "cut-sent" and self.sent[k] >= self.CUT_SENT:
                    break
        except OSError:
            pass
        self._end(client, upstream)

    def _down(self, client, upstream, how, k):
        try:
            while how != "cut":
                data = upstream.recv(1 << 16)
                if not data:
                    break
                client.sendall(data)
            while how == "cut":
                head = recv_exact(upstream, 16)
                payload = recv_exact(upstream, struct.unpack_from("<I", head, 12)[0])
                if how == "cut" and head[5] == 0x83:
                    deadline = time.monotonic() + 10
                    while self.sent[k] < self.hold and time.monotonic() < deadline:
                        time.sleep(0.002)
                    client.sendall(head + payload[:len(payload) // 2])
                    break
                client.sendall(head + payload)
        except OSError:
            pass
        self._end(client, upstream)

    def close(self):
        self.listener.close()


def readme_examples():
    """The ```python blocks of clients/python/README.md."""
    with open(os.path.join(SOURCE, "README.md")) as f:
        return re.findall(r"```python\n(.*?)```", f.read(), re.S)


class InstalledPackage(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.elsewhere = os.path.join(cls.tmp.name, "elsewhere")  # cwd: not the source tree
        os.mkdir(cls.elsewhere)
        src = os.path.join(cls.tmp.name, "src")
        shutil.copytree(SOURCE, src, ignore=shutil.ignore_patterns(
            "build", "*.egg-info", "__pycache__", ".mypy_cache"))
        cls.venv = os.path.join(cls.tmp.name, "venv")
        run([sys.executable, "-m", "venv", "--system-site-packages", cls.venv], cls.elsewhere)
        cls.python = os.path.join(cls.venv, "bin", "python")
        run([cls.python, "-m", "pip", "install", "--no-build-isolation", "--no-index",
             "--disable-pip-version-check", "-q", src], cls.elsewhere)
        cls.purelib = run([cls.python, "-c", "import sysconfig; print(sysconfig.get_paths()"
                           "['purelib'])"], cls.elsewhere).strip()
        cls.server = Server()

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()
        cls.tmp.cleanup()

    def venv_python(self, code):
        """Run `code` in the venv's Python, in a fresh process outside the source tree."""
        return run([self.python, "-c", code], self.elsewhere)

    def test_imports_the_installed_copy(self):
        got = json.loads(self.venv_python(
            "import importlib.metadata, json, os, sdfclient\n"
            "print(json.dumps({'file': sdfclient.__file__, 'version': sdfclient.__version__,"
            " 'dist': importlib.metadata.version('sdfclient'),"
            " 'requires': importlib.metadata.requires('sdfclient'),"
            " 'error': sdfclient.SdfError.__module__ + '.' + sdfclient.SdfError.__name__}))"))
        package = os.path.dirname(got["file"])
        self.assertEqual(package, os.path.join(self.purelib, "sdfclient"))
        self.assertTrue(os.path.isfile(os.path.join(package, "py.typed")), "py.typed not installed")
        self.assertEqual(got["requires"], ["numpy"])
        self.assertEqual(got["error"], "sdfclient.SdfError")
        with open(os.path.join(SOURCE, "sdfclient", "__init__.py")) as f:
            version = [n.value.value for n in ast.parse(f.read()).body if isinstance(n, ast.Assign)
                       and [t.id for t in n.targets] == ["__version__"]]
        self.assertEqual([got["version"], got["dist"]], version * 2)
        # Every source file of the package is installed, unchanged, and nothing else is.
        sources = sorted(f for f in os.listdir(os.path.join(SOURCE, "sdfclient"))
                         if f.endswith(".py") or f == "py.typed")
        self.assertEqual(sorted(f for f in os.listdir(package) if f != "__pycache__"), sources)
        for name in sources:
            with open(os.path.join(SOURCE, "sdfclient", name), "rb") as a, \
                    open(os.path.join(package, name), "rb") as b:
                self.assertEqual(a.read(), b.read(), name)

    def test_queries_sdfd(self):
        points = np.random.default_rng(5).uniform(-3, 3, (64, 3)).astype(np.float32)
        out = os.path.join(self.tmp.name, "answers.npz")
        self.venv_python(
            "import numpy as np, sdfclient\n"
            f"p = np.array({points.tolist()!r}, np.float32)\n"
            f"c = sdfclient.Client({self.server.url!r})\n"
            f"b = sdfclient.BinaryClient('127.0.0.1', {self.server.bin_port})\n"
            "assert [m['name'] for m in c.meshes()] == ['demo'], c.meshes()\n"
            "try:\n"
            "    c.query('no-such-mesh', p)\n"
            "    raise SystemExit('no SdfError')\n"
            "except sdfclient.SdfError as e:\n"
            "    assert (e.status, e.code) == (404, 'ENOTFOUND'), e\n"
            "h = c.query('demo', p, mode='gradient')\n"
            "w = b.query('demo', p, mode='gradient')\n"
            f"np.savez({out!r}, hd=h['distance'], hg=h['gradient'], bd=w['distance'],"
            " bg=w['gradient'])\n")
        body = json.dumps({"points": points.tolist(), "mode": "gradient"}).encode()
        req = urllib.request.Request(f"{self.server.url}/v1/meshes/demo/query", body,
                                     {"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=60) as r:
            ref = json.load(r)
        distance = np.asarray(ref["distance"], np.float32)
        gradient = np.asarray(ref["gradient"], np.float32).reshape(-1, 3)
        self.assertGreater(len(np.unique(distance)), 32)  # distinct answers, not one constant
        with np.load(out) as got:
            for key, want in (("hd", distance), ("bd", distance), ("hg", gradient),
                              ("bg", gradient)):
                self.assertEqual(got[key].dtype, np.float32, key)
                self.assertEqual(got[key].tobytes(), want.tobytes(), key)

    def points_file(self, points):
        """`points` saved where the venv's code can np.load them."""
        path = os.path.join(self.tmp.name, f"points{len(os.listdir(self.tmp.name))}.npy")
        np.save(path, points)
        return path

    def through(self, plan, points, code, options="", hold=0):
        """Run `code` in the venv with `b`, a BinaryClient (with `options`, its constructor's
        keyword arguments as text) through a CutProxy with `plan` (the ports to "pass" to or
        "cut" default to the server's), and `p`, `points`; `code` leaves what it got in
        `out` (a dict of arrays) and the client's counters are added. Returns them and the
        proxy's connection count."""
        proxy = CutProxy([(how, port or self.server.bin_port) for how, port in plan], hold)
        self.addCleanup(proxy.close)
        out = os.path.join(self.tmp.name, "through.npz")
        self.venv_python(
            "import numpy as np, sdfclient\n"
            f"b = sdfclient.BinaryClient('127.0.0.1', {proxy.port}{options})\n"
            f"p = np.load({self.points_file(points)!r})\n"
            "out = {}\n" + code +
            "out.update(connects=b.connects, resent=b.resent)\n"
            f"np.savez({out!r}, **out)\n")
        with np.load(out) as got:
            return {k: got[k] for k in got.files}, proxy.connections

    def test_binary_resends_once_when_the_connection_dies(self):
        p = np.random.default_rng(9).uniform(-3, 3, (300, 3)).astype(np.float32)
        ref = json_query(self.server.url, "demo", p, "gradient")
        self.assertGreater(len(np.unique(ref["distance"])), 100)
        # One query, cut mid-reply: sent again on a second connection, answered bit for bit.
        got, conns = self.through([("cut", 0), ("pass", 0)], p, (
            "r = b.query('demo', p, mode='gradient')\n"
            "out.update(d=r['distance'], g=r['gradient'])\n"))
        self.assertEqual((int(got["connects"]), int(got["resent"]), conns), (2, 1, 2))
        self.assertEqual(got["d"].tobytes(), ref["distance"].tobytes())
        self.assertEqual(got["g"].tobytes(), ref["gradient"].tobytes())
        # Five pipelined: the first reply is cut, so all five go again, in order.
        got, conns = self.through([("cut", 0), ("pass", 0)], p, (
            "rs = b.query_many([('demo', p[60 * i:60 * (i + 1)]) for i in range(5)],"
            " mode='gradient', window=5)\n"
            "out.update(d=np.concatenate([r['distance'] for r in rs]),"
            " g=np.concatenate([r['gradient'] for r in rs]))\n"), hold=5 * 60 * 12)
        self.assertEqual((int(got["connects"]), int(got["resent"]), conns), (2, 5, 2))
        self.assertEqual(got["d"].tobytes(), ref["distance"].tobytes())
        self.assertEqual(got["g"].tobytes(), ref["gradient"].tobytes())
        # A connection that dies twice under the same query: ConnectionError, no third try.
        got, conns = self.through([("cut", 0)], p, (
            "try:\n"
            "    b.query('demo', p)\n"
            "    raise SystemExit('no error')\n"
            "except ConnectionError as e:\n"
            "    assert not isinstance(e, sdfclient.SdfError), e\n"))
        self.assertEqual((int(got["connects"]), int(got["resent"]), conns), (2, 1, 2))

    def test_binary_volume_query_resent(self):
        p = np.random.default_rng(4).uniform(-2, 2, (200, 3)).astype(np.float32)
        got, conns = self.through([("cut", 0), ("pass", 0)], p, (
            f"c = sdfclient.Client({self.server.url!r})\n"
            "c.wait(c.bake('demo', volume='resent', resolution=24, order=1))\n"
            "r = b.query_volume('resent', p, gradient=True)\n"
            f"direct = sdfclient.BinaryClient('127.0.0.1', {self.server.bin_port})\n"
            "w = direct.query_volume('resent', p, gradient=True)\n"
            "assert direct.connects == 1 and direct.resent == 0\n"
            "out.update(d=r['distance'], g=r['gradient'], wd=w['distance'], wg=w['gradient'])\n"))
        self.assertEqual((int(got["connects"]), int(got["resent"]), conns), (2, 1, 2))
        self.assertGreater(len(np.unique(got["wd"])), 100)
        self.assertEqual(got["d"].tobytes(), got["wd"].tobytes())
        self.assertEqual(got["g"].tobytes(), got["wg"].tobytes())

    def test_binary_resends_over_tls_with_its_token(self):
        # The new connection repeats the first one's TLS (CA file, the host name checked) and
        # its AUTH: with --auth-queries an unauthenticated query would be refused.
        d = self.tmp.name
        for args in (["--generate-privkey", "--key-type=ecdsa", "--outfile", f"{d}/ca.key"],
                     ["--generate-self-signed", "--load-privkey", f"{d}/ca.key", "--template",
                      f"{d}/ca.tmpl", "--outfile", f"{d}/ca.pem"],
                     ["--generate-privkey", "--key-type=ecdsa", "--outfile", f"{d}/srv.key"],
                     ["--generate-certificate", "--load-privkey", f"{d}/srv.key",
                      "--load-ca-certificate", f"{d}/ca.pem", "--load-ca-privkey", f"{d}/ca.key",
                      "--template", f"{d}/srv.tmpl", "--outfile", f"{d}/srv.pem"]):
            with open(f"{d}/ca.tmpl", "w") as f:
                f.write('cn = "test CA"\nca\ncert_signing_key\nexpiration_days = 2\n')
            with open(f"{d}/srv.tmpl", "w") as f:
                f.write('cn = "127.0.0.1"\nip_address = "127.0.0.1"\ntls_www_server\n'
                        'signing_key\nencryption_key\nexpiration_days = 2\n')
            subprocess.run(["certtool", *args], check=True, capture_output=True)
        p = np.random.default_rng(8).uniform(-3, 3, (300, 3)).astype(np.float32)
        ref = json_query(self.server.url, "demo", p, "signed")
        with Server("--tls-cert", f"{d}/srv.pem", "--tls-key", f"{d}/srv.key", "--bin-tls",
                    "--token", "sesame", "--auth-queries") as s:
            got, conns = self.through([("cut-sent", s.bin_port), ("pass", s.bin_port)], p, (
                "r = b.query('demo', p)\n"
                "out.update(d=r['distance'], tls=b.sock.version() or '')\n"),
                f", tls=True, cafile={d + '/ca.pem'!r}, token='sesame'")
            self.assertEqual(sum(e.get("method") == "AUTH" and e.get("status") == 200
                                 for e in s.logs), 2)
        self.assertEqual((int(got["connects"]), int(got["resent"]), conns), (2, 1, 2))
        self.assertIn(str(got["tls"]), ("TLSv1.2", "TLSv1.3"))
        self.assertEqual(got["d"].tobytes(), ref["distance"].tobytes())

    def test_binary_query_refused_by_a_draining_server_goes_elsewhere(self):
        # A server that drains (SIGTERM) closes its idle binary connections at once, this
        # client's among them; the client sends the query again on a new connection, which
        # the proxy hands to the other server. A 1 s batch window keeps the drain going
        # meanwhile.
        p = np.random.default_rng(3).uniform(-3, 3, (100, 3)).astype(np.float32)
        with Server("--batch-window-us", "1000000") as draining:
            ref = json_query(self.server.url, "demo", p, "signed")
            proxy = CutProxy([("pass", draining.bin_port), ("pass", self.server.bin_port)])
            self.addCleanup(proxy.close)
            out = os.path.join(self.tmp.name, "drained.npz")
            env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
            client = subprocess.Popen([self.python, "-c", (
                "import sys, numpy as np, sdfclient\n"
                f"b = sdfclient.BinaryClient('127.0.0.1', {proxy.port})\n"
                "b.hello()\n"
                "print('open', flush=True)\n"
                "sys.stdin.readline()\n"
                f"r = b.query('demo', np.load({self.points_file(p)!r}))\n"
                f"np.savez({out!r}, d=r['distance'], connects=b.connects, resent=b.resent)\n")],
                cwd=self.elsewhere, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                text=True)
            self.assertEqual(client.stdout.readline(), "open\n")
            answered = {}
            slow = threading.Thread(target=lambda: answered.update(
                json_query(draining.url, "demo", p, "signed")))
            slow.start()  # in flight for the batch window: the drain waits for it

            def queued():
                with urllib.request.urlopen(draining.url + "/metrics", timeout=5) as r:
                    return metric(r.read().decode(), "sdfd_queue_depth") == 1
            self.assertTrue(wait_until(queued))
            draining.proc.send_signal(signal.SIGTERM)
            self.assertTrue(wait_until(lambda: any(
                "draining" in e.get("message", "") for e in draining.logs)))
            client.stdin.write("go\n")
            client.stdin.flush()
            self.assertEqual(client.wait(60), 0)
            client.stdin.close()
            client.stdout.close()
            slow.join(30)
            self.assertEqual(answered["distance"].tobytes(), ref["distance"].tobytes())
            self.assertEqual(draining.stop(), 0)
            self.assertTrue(any(e.get("message", "").startswith("binary: listener closed")
                                for e in draining.logs), "the binary drain was not logged")
            self.assertFalse(any(e.get("proto") == "binary" and e.get("status") == 503
                                 for e in draining.logs), "a 503, not a closed connection")
        with np.load(out) as got:
            self.assertEqual((int(got["connects"]), int(got["resent"]), proxy.connections),
                             (2, 1, 2))
            self.assertEqual(got["d"].tobytes(), ref["distance"].tobytes())

    def test_slices(self):
        out = os.path.join(self.tmp.name, "slice.npz")
        self.venv_python(
            "import numpy as np, sdfclient\n"
            f"c = sdfclient.Client({self.server.url!r})\n"
            "s = c.slice('demo', axis='x', at=0.5, size=48, format='npy')\n"
            "png = c.slice('demo', axis='x', at=0.5, size=48, mode='filtered', filter={'samples': 8})\n"
            "assert png['bytes'][:8] == b'\\x89PNG\\r\\n\\x1a\\n'\n"
            "j, i = 5, 40\n"
            "p = s['first'] + i * s['right'] + j * s['down']\n"
            f"np.savez({out!r}, values=s['values'], p=p, size=[s['width'], s['height']])\n")
        with np.load(out) as got:
            values, p, (w, h) = got["values"], got["p"], got["size"]
        self.assertEqual(values.shape, (h, w))
        self.assertEqual(max(w, h), 48)
        self.assertAlmostEqual(p[0], 0.5, places=6)
        body = json.dumps({"points": [p.tolist()]}).encode()
        req = urllib.request.Request(f"{self.server.url}/v1/meshes/demo/query", body,
                                     {"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=60) as r:
            self.assertAlmostEqual(json.load(r)["distance"][0], float(values[5, 40]), places=5)

    def test_volume_ops(self):
        """volume_ops and bake's ops= through the installed package: the jobs end done with
        their caveats listed and the results stored on the source's grid; a bad operation is
        the server's 422 as SdfError."""
        out = os.path.join(self.tmp.name, "ops.json")
        self.venv_python(
            "import json, sdfclient\n"
            f"c = sdfclient.Client({self.server.url!r})\n"
            "c.wait(c.bake('demo', volume='ops-src', resolution=[30, 26, 22]))\n"
            "job = c.volume_ops('ops-src', [('round', 0.2), {'fillet': 0.1}], volume='ops-out',\n"
            "                   solver='sussman', iterations=5)\n"
            "done = c.wait(job)\n"
            "baked = c.wait(c.bake('demo', volume='ops-baked', resolution=[30, 26, 22],\n"
            "                      ops=[('offset', -0.1)]))\n"
            "try:\n"
            "    c.volume_ops('ops-src', [{'sharpen': 0.1}])\n"
            "    refused = None\n"
            "except sdfclient.SdfError as e:\n"
            "    refused = [e.status, e.code, e.message]\n"
            "try:\n"
            "    c.volume_ops('ops-src', ['round'])\n"
            "    local = None\n"
            "except ValueError as e:\n"
            "    local = str(e)\n"
            "json.dump({'job': job, 'done': done, 'baked': baked, 'refused': refused,\n"
            "           'local': local, 'src': c.volume('ops-src'), 'out': c.volume('ops-out'),\n"
            f"           'b': c.volume('ops-baked')}}, open({out!r}, 'w'))\n")
        with open(out) as f:
            got = json.load(f)
        self.assertEqual((got["job"]["kind"], got["job"]["source"], got["job"]["volume"]),
                         ("ops", "ops-src", "ops-out"))
        self.assertEqual(got["done"]["state"], "done")
        self.assertIsInstance(got["done"]["caveats"], list)
        self.assertEqual((got["baked"]["state"], got["baked"]["kind"]), ("done", "bake"))
        self.assertIsInstance(got["baked"]["caveats"], list)
        self.assertEqual(got["out"]["dims"], got["src"]["dims"])
        self.assertEqual(got["out"]["dims"], [30, 26, 22])
        self.assertEqual(got["b"]["dims"], [30, 26, 22])
        self.assertEqual(got["refused"][:2], [422, "EINVAL"])
        self.assertIn("sharpen", got["refused"][2])
        self.assertIn("(name, r)", got["local"])

    def test_readme_examples_run(self):
        blocks = readme_examples()
        self.assertEqual(len(blocks), 2)
        for code in blocks:
            live = code.replace('"http://127.0.0.1:8080"', repr(self.server.url)) \
                .replace('("127.0.0.1", 9090)', f'("127.0.0.1", {self.server.bin_port})')
            self.assertNotEqual(live, code, "the example names no server address to replace")
            self.venv_python(live)

    def test_pyflakes(self):
        run([sys.executable, "-m", "pyflakes", os.path.join(SOURCE, "sdfclient")], self.elsewhere)

    def test_mypy(self):
        cache = ["--cache-dir", os.path.join(self.tmp.name, "mypy-cache")]
        run([sys.executable, "-m", "mypy", "--strict", *cache, os.path.join(SOURCE, "sdfclient")],
            self.elsewhere)
        # A user's project: the venv's Python, whose site-packages hold the installed package;
        # without py.typed mypy would refuse it ("missing library stubs or py.typed marker").
        good = os.path.join(self.elsewhere, "good.py")
        with open(good, "w") as f:
            f.write("\n".join(readme_examples()))
        run([self.python, "-m", "mypy", "--strict", *cache, good], self.elsewhere)
        bad = os.path.join(self.elsewhere, "bad.py")
        with open(bad, "w") as f:
            f.write("import sdfclient\n"
                    "c = sdfclient.Client('http://127.0.0.1:1')\n"
                    "n: int = c.metrics()\n"
                    "r = c.query('demo', [[0, 0, 0]], mode='sideways')\n"
                    "v = c.query_volume('v', [[0, 0, 0]], interpolation='cubic')\n")
        text = run([self.python, "-m", "mypy", "--strict", *cache, bad], self.elsewhere, expect=1)
        self.assertIn('bad.py:3: error: Incompatible types in assignment (expression has type '
                      '"str", variable has type "int")', text)
        self.assertRegex(text, r'bad.py:4: error: Argument "mode" to "query" of "Client" has '
                               r'incompatible type "Literal\[.sideways.\]"')
        self.assertRegex(text, r'bad.py:5: error: Argument "interpolation" to "query_volume" of '
                               r'"Client" has incompatible type "Literal\[.cubic.\]"')
        self.assertIn("Found 3 errors", text)


if __name__ == "__main__":
    unittest.main(verbosity=2)
