"""A soak test of sdfd (issue 34): one sdfd on loopback ports, with a data directory in a
temporary folder and a small --max-resident-bytes (so meshes and volumes leave memory and are
loaded again from the store), under a mixed and bounded load for a set time:

  - mesh queries of every mode (signed with each sign, distance, gradient, closest, filtered,
    filtered-gradient) in every body form (JSON, octet-stream, npy) over HTTP, and over the
    binary protocol, one frame at a time and pipelined;
  - volume queries (value and gradient, trilinear and nearest) over both;
  - mesh uploads, queries of the uploaded mesh and deletes; bakes, some cancelled at once;
  - slow clients (half a request, a pause, the rest), abandoned ones (connect and close, half
    a request, a query whose answer is never read), malformed requests on both protocols.

Every answer is compared bit for bit with the library's: sdf-bench (sdf_query and
sdf_query_filtered) and sdf-volume (sdf_volume_eval on the EXR the server baked) compute the
expected floats before the load starts, on the same points. Every request's status must be
the one expected for it; 429 and 503 are allowed (documented refusals under overload) and
reported. Every 10 s it prints throughput, p50/p99 latency per route, statuses, and sdfd's
resident memory, open descriptors and threads (/proc).

Warm-up and the memory check: the first WARMUP of the run (20 %) is warm-up. It ends with a
quiet pause: the load stops, the clients close their connections, and after --timeout plus a
second (so the server has closed what abandoned clients left) sdfd's RSS and descriptors are
read: the baseline. The run ends with the same pause and the same reading. Descriptors at the
end must be within the tolerance (5 %) of the baseline, RSS within the tolerance or
--rss-slack MiB (default 3), whichever is larger: on a process of about 20 MiB, 5 % is 1 MiB,
less than what a 2-minute run still adds (docs/robustness.md, "Soak").

Exit status: 0 when every check passed, 1 otherwise (the summary says which failed). Standard
library only, so that it runs with any python3."""
import argparse
import http.client
import json
import os
import random
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse

HEADER = struct.Struct("<4sBBHII")
MODES = {"signed": 0, "distance": 1, "gradient": 2, "closest": 3, "filtered": 4,
         "filtered-gradient": 5}
SIGNS = {"auto": 0, "pseudonormal": 1, "winding": 2, "raycast": 3, "none": 4}
WORDS = {"signed": 1, "distance": 1, "gradient": 4, "closest": 5, "filtered": 1,
         "filtered-gradient": 4}
SAMPLES = 16  # the filtered modes' samples: cheap enough to be a small part of the load
TIMEOUT = 3   # sdfd's --timeout


# ---- npy and float helpers --------------------------------------------------------------

def npy_bytes(floats, shape):
    header = "{'descr': '<f4', 'fortran_order': False, 'shape': %s, }" % (shape,)
    header += " " * (-(len(header) + 11) % 64) + "\n"
    return (b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode()
            + struct.pack("<%df" % len(floats), *floats))


def npy_data(blob):
    """The array bytes of a .npy file (versions 1-3)."""
    if blob[:6] != b"\x93NUMPY":
        raise ValueError("not an npy file")
    if blob[6] == 1:
        (n,) = struct.unpack_from("<H", blob, 8)
        return blob[10 + n:]
    (n,) = struct.unpack_from("<I", blob, 8)
    return blob[12 + n:]


def words_of(blob, w):
    """Split little-endian 32-bit words into per-point tuples of w raw words."""
    count = len(blob) // 4
    flat = struct.unpack("<%dI" % count, blob)
    return [flat[i:i + w] for i in range(0, count, w)]


def f32_bits(x):
    return struct.unpack("<I", struct.pack("<f", x))[0]


# ---- the expected answers ---------------------------------------------------------------

class Reference:
    """Points and the library's answers for them, as raw float32 words per point."""

    def __init__(self, tools, tmp, data):
        self.tools, self.tmp, self.data = tools, tmp, data
        self.points = {}    # (mesh, set) -> list of floats (x, y, z, ...)
        self.expected = {}  # (mesh, set, mode, sign) -> [tuple of words]
        self.volume = {}    # (set, gradient, interpolation) -> [tuple of words]

    def run(self, *args):
        subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)

    def make_points(self, mesh, path, sets, n):
        for k in range(sets):
            p = os.path.join(self.tmp, f"{mesh}-{k}.npy")
            self.run(self.tools["sdf-bench"], path, "--workload", "box", "--n", str(n),
                     "--seed", str(11 + k), "--repeat", "1", "--points-out", p,
                     "--out", os.path.join(self.tmp, "scratch.npy"))
            with open(p, "rb") as f:
                raw = npy_data(f.read())
            self.points[(mesh, k)] = list(struct.unpack("<%df" % (len(raw) // 4), raw))

    def mesh_answers(self, mesh, path, sets, combos):
        for k in range(sets):
            pts = os.path.join(self.tmp, f"{mesh}-{k}.npy")
            for mode, sign in combos:
                out = os.path.join(self.tmp, "out.npy")
                extra = ["--samples", str(SAMPLES)] if mode.startswith("filtered") else []
                self.run(self.tools["sdf-bench"], path, pts, "--mode", mode, "--sign", sign,
                         "--repeat", "1", "--out", out, *extra)
                with open(out, "rb") as f:
                    # sdf-bench writes closest as (N, 4): distance and point, no triangle
                    w = 4 if mode == "closest" else WORDS[mode]
                    self.expected[(mesh, k, mode, sign)] = words_of(npy_data(f.read()), w)

    def volume_answers(self, exr, sets):
        for k in range(sets):
            pts = os.path.join(self.tmp, f"fandisk-{k}.npy")
            for gradient in (False, True):
                for interp in ("trilinear", "nearest"):
                    out = os.path.join(self.tmp, "vout.npy")
                    self.run(self.tools["sdf-volume"], "eval", exr, pts, out, "--interpolation",
                             interp, *(["--gradient"] if gradient else []))
                    with open(out, "rb") as f:
                        self.volume[(k, gradient, interp)] = words_of(npy_data(f.read()),
                                                                      4 if gradient else 1)


def check_words(got, expected, mode, triangles, key):
    """Compare an answer's words with the library's; closest's triangle ids are compared
    with the first answer's for the same points (sdf-bench does not write them)."""
    if len(got) != len(expected):
        return f"{len(got)} points, expected {len(expected)}"
    if mode == "closest":
        if [g[:4] for g in got] != expected:
            return "closest: floats differ from the library's"
        tris = [g[4] for g in got]
        first = triangles.setdefault(key, tris)
        return None if first == tris else "closest: triangle ids changed"
    return None if got == expected else f"{mode}: floats differ from the library's"


def json_words(answer, mode):
    """A JSON answer as per-point word tuples."""
    d = [f32_bits(x) for x in answer["distance"]]
    if mode in ("gradient", "filtered-gradient"):
        return [(d[i], *map(f32_bits, g)) for i, g in enumerate(answer["gradient"])]
    if mode == "closest":
        return [(d[i], *map(f32_bits, c), t)
                for i, (c, t) in enumerate(zip(answer["closest"], answer["triangle"]))]
    return [(x,) for x in d]


# ---- statistics ---------------------------------------------------------------------------

class Stats:
    def __init__(self):
        self.lock = threading.Lock()
        self.window = {}   # route -> [latencies] since the last report
        self.total = {}    # route -> [latencies]
        self.status = {}   # route -> {status: count}
        self.unexpected = []
        self.wrong = []

    def record(self, route, status, seconds, ok=True, detail=""):
        with self.lock:
            self.window.setdefault(route, []).append(seconds)
            self.total.setdefault(route, []).append(seconds)
            codes = self.status.setdefault(route, {})
            codes[status] = codes.get(status, 0) + 1
            if not ok and len(self.unexpected) < 10000:
                self.unexpected.append(f"{route}: {status} {detail}"[:300])

    def wrong_answer(self, route, detail):
        with self.lock:
            self.wrong.append(f"{route}: {detail}")

    def take_window(self):
        with self.lock:
            w, self.window = self.window, {}
            return w


def pct(values, q):
    if not values:
        return 0.0
    v = sorted(values)
    return v[min(len(v) - 1, int(q * len(v)))]


# ---- the server ---------------------------------------------------------------------------

class Sdfd:
    def __init__(self, binary, tmp, resident):
        self.store = os.path.join(tmp, "store")
        self.log = open(os.path.join(tmp, "sdfd.log"), "wb+")
        self.proc = subprocess.Popen(
            [binary, "--http", "127.0.0.1:0", "--bin", "127.0.0.1:0", "--data-dir", self.store,
             "--max-resident-bytes", str(resident), "--timeout", str(TIMEOUT),
             "--max-jobs", "16"], stdout=subprocess.DEVNULL, stderr=self.log)
        self.ports = {}
        deadline = time.time() + 60
        while time.time() < deadline and "ready" not in self.ports:
            if self.proc.poll() is not None:
                raise RuntimeError("sdfd exited at start:\n" + self.log_tail())
            self.ports = self.read_ports()
            time.sleep(0.1)
        if "ready" not in self.ports:
            raise RuntimeError("sdfd did not become ready:\n" + self.log_tail())

    def read_ports(self):
        ports = {}
        with open(self.log.name, "rb") as f:
            for line in f:
                try:
                    e = json.loads(line)
                except ValueError:
                    continue
                if e.get("event") == "listening":
                    ports[e["proto"]] = e["port"]
                if e.get("event") == "ready":
                    ports["ready"] = True
        return ports

    def log_tail(self, n=40):
        with open(self.log.name, "rb") as f:
            return b"".join(f.readlines()[-n:]).decode(errors="replace")

    def proc_figures(self):
        pid = self.proc.pid
        rss = threads = 0
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    rss = int(line.split()[1]) * 1024
                elif line.startswith("Threads:"):
                    threads = int(line.split()[1])
        return rss, len(os.listdir(f"/proc/{pid}/fd")), threads

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()


# ---- clients ------------------------------------------------------------------------------

def bin_frame(type_, rid, payload):
    return HEADER.pack(b"SDFP", 1, type_, 0, rid, len(payload)) + payload


def padded(name):
    b = name.encode()
    return b + b"\0" * (-len(b) % 4)


def query_payload(mesh, pts, mode, sign):
    block = b""
    if mode.startswith("filtered"):  # the FILTER block: samples, the rest 0 (defaults)
        block = struct.pack("<BBBBIdddQdd6dIId", 0, 0, 0, 0, SAMPLES, 0, 0, 0, 0, 0, 0,
                            *([0.0] * 6), 0, 0, 0)
    return (struct.pack("<BBHI", MODES[mode], SIGNS[sign], len(mesh.encode()), len(pts) // 3)
            + padded(mesh) + block + struct.pack("<%df" % len(pts), *pts))


def volume_payload(name, pts, gradient, interp):
    return (struct.pack("<BBHI", int(gradient), {"trilinear": 0, "nearest": 1}[interp],
                        len(name.encode()), len(pts) // 3)
            + padded(name) + struct.pack("<%df" % len(pts), *pts))


class BinConn:
    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=60)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.rid = 0

    def send(self, type_, payload):
        self.rid += 1
        self.sock.sendall(bin_frame(type_, self.rid, payload))
        return self.rid

    def exact(self, n):
        out = bytearray()
        while len(out) < n:
            chunk = self.sock.recv(min(n - len(out), 1 << 20))
            if not chunk:
                raise ConnectionError("sdfd closed the binary connection")
            out += chunk
        return bytes(out)

    def recv(self):
        magic, _, type_, _, rid, length = HEADER.unpack(self.exact(16))
        return type_, rid, self.exact(length)

    def close(self):
        self.sock.close()


def bin_status(type_, payload):
    if type_ == 0x7F:
        (status,) = struct.unpack_from("<H", payload)
        return status
    return 200


class Worker(threading.Thread):
    """One client thread: runs `action` over and over until the run ends, pausing when
    asked (closing its connections first)."""

    def __init__(self, soak, name, action):
        super().__init__(daemon=True, name=name)
        self.soak, self.action = soak, action
        self.http = None
        self.bin = None
        self.idle = threading.Event()
        self.rng = random.Random(name)  # str seeds are hashed with SHA-512: stable

    def conn(self):
        if self.http is None:
            self.http = http.client.HTTPConnection("127.0.0.1", self.soak.http_port, timeout=60)
        return self.http

    def binconn(self):
        if self.bin is None:
            self.bin = BinConn(self.soak.bin_port)
        return self.bin

    def drop(self):
        for c in (self.http, self.bin):
            if c is not None:
                c.close()
        self.http = self.bin = None

    def request(self, method, path, body=None, headers=None):
        """One HTTP request on the keep-alive connection; (status, headers, body). A
        connection the server closed while idle (its --timeout) is opened again once."""
        for attempt in (0, 1):
            c = self.conn()
            try:
                c.request(method, path, body=body, headers=headers or {})
                r = c.getresponse()
                return r.status, r, r.read()
            except (http.client.RemoteDisconnected, BrokenPipeError, ConnectionResetError):
                self.drop()
                if attempt:
                    raise

    def run(self):
        s = self.soak
        while not s.done.is_set():
            if s.paused.is_set():
                self.drop()
                self.idle.set()
                s.resume.wait()
                self.idle.clear()
                continue
            try:
                self.action(self)
            except Exception as e:  # noqa: BLE001 - every failure is counted
                s.stats.record(self.name, f"EXC {type(e).__name__}", 0.0, False, str(e))
                self.drop()
        self.drop()
        self.idle.set()


# ---- the load -----------------------------------------------------------------------------

OVERLOAD = (429, 503)


class Soak:
    def __init__(self, args, tools, tmp):
        self.args, self.tools, self.tmp = args, tools, tmp
        self.stats = Stats()
        self.done, self.paused, self.resume = threading.Event(), threading.Event(), threading.Event()
        self.triangles = {}
        self.tri_lock = threading.Lock()
        self.churn_seq = 0

    # -- setup --

    def setup(self):
        data = self.args.data
        self.meshes = {"fandisk": os.path.join(data, "fandisk.off"),
                       "cow": os.path.join(data, "cow.off")}
        self.ref = Reference(self.tools, self.tmp, data)
        self.ref.make_points("fandisk", self.meshes["fandisk"], 4, 200)
        self.ref.make_points("cow", self.meshes["cow"], 2, 200)
        self.combos = [("signed", s) for s in ("auto", "winding", "raycast", "none")] + \
            [(m, "auto") for m in ("distance", "gradient", "closest", "filtered",
                                   "filtered-gradient")]
        self.ref.mesh_answers("fandisk", self.meshes["fandisk"], 4, self.combos)
        self.ref.mesh_answers("cow", self.meshes["cow"], 2, [("signed", "auto"),
                                                             ("closest", "auto")])
        self.server = Sdfd(self.tools["sdfd"], self.tmp, self.args.resident)
        self.http_port, self.bin_port = self.server.ports["http"], self.server.ports["binary"]
        c = http.client.HTTPConnection("127.0.0.1", self.http_port, timeout=120)
        with open(self.meshes["fandisk"], "rb") as f:
            self.expect(c, "PUT", "/v1/meshes/fandisk?format=off", f.read(), (201,))
        with open(self.meshes["cow"], "rb") as f:
            self.cow = f.read()
        job = json.loads(self.expect(c, "POST", "/v1/meshes/fandisk/bake", json.dumps(
            {"volume": "vol", "resolution": 24, "order": 1}).encode(), (202,)))
        while True:
            state = json.loads(self.expect(c, "GET", f"/v1/jobs/{job['id']}", None, (200,)))
            if state["state"] == "done":
                break
            if state["state"] in ("failed", "canceled"):
                raise RuntimeError(f"the setup bake ended {state}")
            time.sleep(0.2)
        exr = os.path.join(self.tmp, "vol.exr")
        with open(exr, "wb") as f:
            f.write(self.expect(c, "GET", "/v1/volumes/vol/data?format=exr", None, (200,)))
        c.close()
        self.ref.volume_answers(exr, 4)

    @staticmethod
    def expect(c, method, path, body, statuses):
        c.request(method, path, body=body)
        r = c.getresponse()
        data = r.read()
        if r.status not in statuses:
            raise RuntimeError(f"setup: {method} {path}: {r.status} {data[:200]!r}")
        return data

    # -- actions: each records one or more requests --

    def timed(self, w, route, fn, expect=(200,), allow=OVERLOAD):
        t0 = time.perf_counter()
        status, detail = fn()
        dt = time.perf_counter() - t0
        ok = status in expect or status in allow
        self.stats.record(route, status, dt, ok, detail if not ok else "")
        return status in expect

    def check(self, route, got, key, mode, expected):
        with self.tri_lock:
            why = check_words(got, expected, mode, self.triangles, key)
        if why:
            self.stats.wrong_answer(route, f"{key}: {why}")

    def http_query(self, w):
        mesh = "fandisk"
        k = w.rng.randrange(4)
        mode, sign = w.rng.choice(self.combos)
        form = w.rng.choice(("json", "octet", "npy"))
        pts = self.ref.points[(mesh, k)]
        self.http_mesh_query(w, mesh, k, mode, sign, form, pts, f"http query {form}")

    def http_mesh_query(self, w, mesh, k, mode, sign, form, pts, route, expect=(200,),
                        ref_mesh=None):
        args = {"mode": mode, "sign": sign}
        if mode.startswith("filtered"):
            args["samples"] = SAMPLES
        if form == "json":
            body = {"points": pts, "mode": mode, "sign": sign}
            if mode.startswith("filtered"):
                body["filter"] = {"samples": SAMPLES}
            data, ctype, path = json.dumps(body).encode(), "application/json", ""
        elif form == "octet":
            data = struct.pack("<%df" % len(pts), *pts)
            ctype, path = "application/octet-stream", "?" + urllib.parse.urlencode(args)
        else:
            data = npy_bytes(pts, (len(pts) // 3, 3))
            ctype, path = "application/x-npy", "?" + urllib.parse.urlencode(args)
        out = {}

        def go():
            status, r, body = w.request("POST", f"/v1/meshes/{mesh}/query{path}", data,
                                        {"Content-Type": ctype})
            out["body"] = body
            return status, body[:200]
        if self.timed(w, route, go, expect) and 200 in expect:
            body = out["body"]
            if form == "json":
                got = json_words(json.loads(body), mode)
            else:
                got = words_of(npy_data(body) if form == "npy" else body, WORDS[mode])
            self.check(route, got, (mesh, k, mode, sign),
                       mode, self.ref.expected[(ref_mesh or mesh, k, mode, sign)])

    def bin_query(self, w):
        """One QUERY, or (one time in three) four pipelined on the connection."""
        b = w.binconn()
        sent = {}
        for _ in range(4 if w.rng.random() < 1 / 3 else 1):
            k = w.rng.randrange(4)
            mode, sign = w.rng.choice(self.combos)
            rid = b.send(0x03, query_payload("fandisk", self.ref.points[("fandisk", k)], mode,
                                             sign))
            sent[rid] = (k, mode, sign, time.perf_counter())
        route = "bin query" if len(sent) == 1 else "bin query pipelined"
        while sent:
            type_, rid, payload = b.recv()
            k, mode, sign, t0 = sent.pop(rid)
            status = bin_status(type_, payload)
            ok = status == 200 or status in OVERLOAD
            self.stats.record(route, status, time.perf_counter() - t0, ok,
                              "" if ok else payload[:200].decode(errors="replace"))
            if status == 200:
                m, words, _, count = struct.unpack_from("<BBHI", payload)
                self.check(route, words_of(payload[8:], words), ("fandisk", k, mode, sign),
                           mode, self.ref.expected[("fandisk", k, mode, sign)])

    def volume_query(self, w):
        k = w.rng.randrange(4)
        gradient = w.rng.random() < 0.5
        interp = w.rng.choice(("trilinear", "nearest"))
        pts = self.ref.points[("fandisk", k)]
        expected = self.ref.volume[(k, gradient, interp)]
        key = ("vol", k, gradient, interp)
        if w.rng.random() < 0.5:
            b = w.binconn()
            t0 = time.perf_counter()
            b.send(0x04, volume_payload("vol", pts, gradient, interp))
            type_, _, payload = b.recv()
            status = bin_status(type_, payload)
            ok = status == 200 or status in OVERLOAD
            self.stats.record("bin volume query", status, time.perf_counter() - t0, ok)
            if status == 200:
                self.check("bin volume query", words_of(payload[8:], 4 if gradient else 1), key,
                           "volume", expected)
            return
        form = w.rng.choice(("octet", "json"))
        mode = "gradient" if gradient else "value"
        out = {}
        if form == "json":
            data, ctype, q = json.dumps({"points": pts, "mode": mode,
                                         "interpolation": interp}).encode(), "application/json", ""
        else:
            data = struct.pack("<%df" % len(pts), *pts)
            ctype = "application/octet-stream"
            q = "?" + urllib.parse.urlencode({"mode": mode, "interpolation": interp})

        def go():
            status, r, body = w.request("POST", f"/v1/volumes/vol/query{q}", data,
                                        {"Content-Type": ctype})
            out["body"] = body
            return status, body[:200]
        route = f"http volume query {form}"
        if self.timed(w, route, go):
            if form == "json":
                got = json_words(json.loads(out["body"]), "gradient" if gradient else "signed")
            else:
                got = words_of(out["body"], 4 if gradient else 1)
            self.check(route, got, key, "volume", expected)

    def churn(self, w):
        """Upload a mesh under a new name, query it (both protocols), delete it, and see it
        gone."""
        with self.tri_lock:
            self.churn_seq += 1
            name = f"churn-{self.churn_seq % 5}"

        def put():
            status, r, body = w.request("PUT", f"/v1/meshes/{name}?format=off", self.cow)
            return status, body[:200]
        if not self.timed(w, "put mesh", put, (201, 200)):
            return
        k = w.rng.randrange(2)
        mode = w.rng.choice(("signed", "closest"))
        pts = self.ref.points[("cow", k)]
        self.http_mesh_query(w, name, k, mode, "auto", w.rng.choice(("json", "octet", "npy")),
                             pts, "http query churn", ref_mesh="cow")
        b = w.binconn()
        t0 = time.perf_counter()
        b.send(0x03, query_payload(name, pts, mode, "auto"))
        type_, _, payload = b.recv()
        status = bin_status(type_, payload)
        self.stats.record("bin query churn", status, time.perf_counter() - t0,
                          status == 200 or status in OVERLOAD)
        if status == 200:
            self.check("bin query churn", words_of(payload[8:], WORDS[mode]),
                       (name, k, mode, "auto"), mode, self.ref.expected[("cow", k, mode, "auto")])

        def delete():
            status, r, body = w.request("DELETE", f"/v1/meshes/{name}")
            return status, body[:200]
        self.timed(w, "delete mesh", delete, (204,))
        self.http_mesh_query(w, name, k, "signed", "auto", "octet", pts,
                             "http query deleted", expect=(404,))
        with self.tri_lock:  # a new upload under the name starts afresh
            for key in [key for key in self.triangles if key[0] == name]:
                del self.triangles[key]

    def bake(self, w):
        """A small bake of fandisk, cancelled at once half of the time; then the job and the
        volume are forgotten."""
        vol = f"tmp-{w.rng.randrange(3)}"
        out = {}

        def start():
            status, r, body = w.request("POST", "/v1/meshes/fandisk/bake", json.dumps(
                {"volume": vol, "resolution": 16, "order": w.rng.choice((0, 1))}).encode(),
                {"Content-Type": "application/json"})
            out["body"] = body
            return status, body[:200]
        if not self.timed(w, "bake", start, (202,)):
            return
        job = json.loads(out["body"])["id"]
        cancelled = w.rng.random() < 0.5
        if cancelled:
            def cancel():
                status, r, body = w.request("DELETE", f"/v1/jobs/{job}")
                return status, body[:200]
            self.timed(w, "cancel bake", cancel)
        deadline = time.time() + 120
        state = None
        while time.time() < deadline:
            status, r, body = w.request("GET", f"/v1/jobs/{job}")
            state = json.loads(body).get("state") if status == 200 else status
            if state in ("done", "canceled", "failed") or status != 200:
                break
            time.sleep(0.1)
        # A job cancelled while queued may be gone by the time it is asked for.
        ok = state in ("done", "canceled") or (cancelled and state == 404)
        self.stats.record("bake finished", state, 0.0, ok)
        if state == 404:
            return

        def forget():
            status, r, body = w.request("DELETE", f"/v1/jobs/{job}")
            return status, body[:200]
        self.timed(w, "forget job", forget)
        if state == "done":
            def drop():
                status, r, body = w.request("DELETE", f"/v1/volumes/{vol}")
                return status, body[:200]
            self.timed(w, "delete volume", drop, (204, 404))  # another bake may share the name

    def abuse(self, w):
        """A slow, an abandoned or a malformed request."""
        kind = w.rng.randrange(10)
        port = self.http_port
        pts = self.ref.points[("fandisk", 0)]
        body = struct.pack("<%df" % len(pts), *pts)
        head = (b"POST /v1/meshes/fandisk/query HTTP/1.1\r\nHost: x\r\n"
                b"Content-Type: application/octet-stream\r\nContent-Length: %d\r\n\r\n" % len(body))
        if kind == 0:  # slow: half the request, a pause, the rest
            t0 = time.perf_counter()
            s = socket.create_connection(("127.0.0.1", port), timeout=30)
            s.sendall(head + body[:len(body) // 2])
            time.sleep(1.0)
            s.sendall(body[len(body) // 2:])
            data = b""
            while b"\r\n\r\n" not in data or len(data.split(b"\r\n\r\n", 1)[1]) < 4 * len(pts) // 3:
                chunk = s.recv(65536)
                if not chunk:
                    break
                data += chunk
            s.close()
            status = int(data.split(b" ", 2)[1]) if data.startswith(b"HTTP/1.1 ") else 0
            self.stats.record("slow http", status, time.perf_counter() - t0,
                              status == 200 or status in OVERLOAD)
            if status == 200:
                self.check("slow http", words_of(data.split(b"\r\n\r\n", 1)[1], 1),
                           ("fandisk", 0, "signed", "auto"), "signed",
                           self.ref.expected[("fandisk", 0, "signed", "auto")])
        elif kind in (1, 2, 3):  # abandoned: connect and close, half a request, no reading
            t0 = time.perf_counter()
            if kind == 3 and w.rng.random() < 0.5:
                s = socket.create_connection(("127.0.0.1", self.bin_port), timeout=30)
                s.sendall(bin_frame(0x03, 1, query_payload("fandisk", pts, "signed", "auto")))
            else:
                s = socket.create_connection(("127.0.0.1", port), timeout=30)
                s.sendall((b"", head + body[:100], head + body)[kind - 1])
            s.close()
            self.stats.record("abandoned", "closed", time.perf_counter() - t0)
        elif kind in (4, 5, 6, 7):  # malformed HTTP
            path, data, ctype, expect = [
                ("/v1/meshes/fandisk/query", b'{"points": [0,0,', "application/json", 400),
                ("/v1/meshes/fandisk/query", body[:-1], "application/octet-stream", 400),
                ("/v1/meshes/nosuch/query", body, "application/octet-stream", 404),
                ("/v1/meshes/fandisk/query?mode=sideways", body, "application/octet-stream",
                 422)][kind - 4]

            def go():
                status, r, reply = w.request("POST", path, data, {"Content-Type": ctype})
                return status, reply[:200]
            self.timed(w, "malformed http", go, (expect,), ())
        elif kind == 8:  # a bad binary frame: an ERROR, then the server closes
            t0 = time.perf_counter()
            b = BinConn(self.bin_port)
            b.sock.sendall(b"GET / HTTP/1.1\r\n\r\n")
            try:
                type_, _, payload = b.recv()
                status = bin_status(type_, payload)
                try:
                    closed = b.sock.recv(1) == b""
                except OSError:  # a reset is a close too
                    closed = True
            finally:
                b.close()
            self.stats.record("malformed bin", status, time.perf_counter() - t0,
                              type_ == 0x7F and 400 <= status < 500 and closed,
                              "" if closed else "not closed")
        else:  # a binary query of an unknown mesh: an ERROR, the connection goes on
            b = w.binconn()
            t0 = time.perf_counter()
            b.send(0x03, query_payload("nosuch", pts, "signed", "auto"))
            type_, _, payload = b.recv()
            status = bin_status(type_, payload)
            self.stats.record("malformed bin", status, time.perf_counter() - t0, status == 404)

    # -- the run --

    def pause_and_measure(self, workers):
        """Stop the load, let the server close what the clients left, read /proc."""
        self.resume.clear()
        self.paused.set()
        for w in workers:
            w.idle.wait(120)
        time.sleep(TIMEOUT + 1.5)
        figures = self.server.proc_figures()
        self.paused.clear()
        self.resume.set()
        return figures

    def report(self, elapsed, window, seconds):
        rss, fds, threads = self.server.proc_figures()
        n = sum(len(v) for v in window.values())
        with self.stats.lock:
            codes = {}
            for route, st in self.stats.status.items():
                for code, count in st.items():
                    if code not in (200, 201, 202, 204, "closed", "done", "canceled"):
                        codes[code] = codes.get(code, 0) + count
            wrong, unexpected = len(self.stats.wrong), len(self.stats.unexpected)
        print(f"[{elapsed:6.0f} s] {n / seconds:7.1f} req/s  RSS {rss / 2**20:6.1f} MiB  "
              f"fds {fds:4d}  threads {threads:3d}  other statuses so far {codes or '{}'}  "
              f"unexpected {unexpected}  wrong answers {wrong}", flush=True)
        line = "    "
        for route in sorted(window):
            v = window[route]
            line += f"{route}: {len(v)} {pct(v, .5) * 1e3:.1f}/{pct(v, .99) * 1e3:.1f} ms; "
        print(line.rstrip("; "), flush=True)

    def run(self):
        a = self.args
        actions = [("http-query-1", self.http_query), ("http-query-2", self.http_query),
                   ("bin-query-1", self.bin_query), ("bin-query-2", self.bin_query),
                   ("volume", self.volume_query), ("churn", self.churn), ("bake", self.bake),
                   ("abuse-1", self.abuse), ("abuse-2", self.abuse)]
        workers = [Worker(self, name, fn) for name, fn in actions]
        total = a.minutes * 60
        warmup = total * a.warmup
        print(f"sdfd pid {self.server.proc.pid}, HTTP {self.http_port}, binary {self.bin_port}; "
              f"{total:.0f} s, warm-up {warmup:.0f} s; per route: requests p50/p99 ms",
              flush=True)
        t0 = time.time()
        for w in workers:
            w.start()
        base = end = None
        last = t0
        while True:
            time.sleep(min(a.every, max(0.1, t0 + total - time.time())))
            now = time.time()
            if self.server.proc.poll() is not None:
                break
            self.report(now - t0, self.stats.take_window(), now - last)
            last = now
            if base is None and now - t0 >= warmup:
                base = self.pause_and_measure(workers)
                print(f"baseline after warm-up (load paused): RSS {base[0] / 2**20:.1f} MiB, "
                      f"fds {base[1]}, threads {base[2]}", flush=True)
                last = time.time()
            if now - t0 >= total:
                break
        crashed = self.server.proc.poll() is not None
        if not crashed:
            end = self.pause_and_measure(workers)
        self.done.set()
        self.resume.set()
        for w in workers:
            w.join(120)
        return self.summary(time.time() - t0, base, end, crashed)

    def summary(self, seconds, base, end, crashed):
        s = self.stats
        print("\n| route | requests | req/s | p50 ms | p99 ms | statuses |")
        print("| --- | ---: | ---: | ---: | ---: | --- |")
        n = 0
        for route in sorted(s.total):
            v = s.total[route]
            n += len(v)
            codes = ", ".join(f"{k}: {c}" for k, c in sorted(s.status[route].items(), key=str))
            print(f"| {route} | {len(v)} | {len(v) / seconds:.1f} | {pct(v, .5) * 1e3:.2f} | "
                  f"{pct(v, .99) * 1e3:.2f} | {codes} |")
        print(f"| all | {n} | {n / seconds:.1f} | | | |")
        failures = []
        if crashed:
            failures.append(f"sdfd exited with {self.server.proc.returncode}:\n"
                            + self.server.log_tail())
        fives = {c: k for st in s.status.values() for c, k in st.items()
                 if isinstance(c, int) and c >= 500 and c not in OVERLOAD}
        if fives:
            failures.append(f"5xx statuses: {fives}")
        if s.unexpected:
            failures.append(f"{len(s.unexpected)} unexpected outcomes, e.g. {s.unexpected[:5]}")
        if s.wrong:
            failures.append(f"{len(s.wrong)} wrong answers, e.g. {s.wrong[:5]}")
        tol = self.args.tolerance
        if base and end:
            print(f"\nsdfd after warm-up -> at the end (load paused, connections closed): RSS "
                  f"{base[0] / 2**20:.1f} -> {end[0] / 2**20:.1f} MiB "
                  f"({(end[0] / base[0] - 1) * 100:+.1f} %), fds {base[1]} -> {end[1]}, "
                  f"threads {base[2]} -> {end[2]}")
            slack = self.args.rss_slack * 2**20
            if end[0] > max(base[0] * (1 + tol), base[0] + slack):
                failures.append(f"RSS grew {(end[0] / base[0] - 1) * 100:.1f} % (bound "
                                f"{tol * 100:.0f} % or {self.args.rss_slack:g} MiB)")
            if end[1] > base[1] * (1 + tol):
                failures.append(f"descriptors grew from {base[1]} to {end[1]}")
        elif not crashed:
            failures.append("the run ended before its warm-up did: no memory figures")
        code = self.server.stop()
        if code != 0 and not crashed:
            failures.append(f"sdfd exited {code} on SIGTERM:\n{self.server.log_tail()}")
        overload = sum(k for st in s.status.values() for c, k in st.items() if c in OVERLOAD)
        print(f"overload refusals (429/503): {overload}; unexpected outcomes: "
              f"{len(s.unexpected)}; wrong answers: {len(s.wrong)}")
        print("\nsoak: " + ("PASS" if not failures else "FAIL\n  " + "\n  ".join(failures)))
        return 0 if not failures else 1


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=2.0)
    p.add_argument("--build", default="build", help="meson build directory")
    p.add_argument("--data", default=os.path.join(os.path.dirname(__file__), "..", "data"))
    p.add_argument("--resident", type=int, default=4 << 20, help="--max-resident-bytes")
    p.add_argument("--warmup", type=float, default=0.2, help="warm-up, a fraction of the run")
    p.add_argument("--tolerance", type=float, default=0.05, help="RSS and fd growth allowed")
    p.add_argument("--rss-slack", type=float, default=3.0,
                   help="MiB of RSS growth allowed when more than the tolerance")
    p.add_argument("--every", type=float, default=10.0, help="seconds between reports")
    args = p.parse_args()
    tools = {"sdfd": os.path.join(args.build, "server", "sdfd"),
             "sdf-bench": os.path.join(args.build, "tests", "bench", "sdf-bench"),
             "sdf-volume": os.path.join(args.build, "tests", "bench", "sdf-volume")}
    for name, path in tools.items():
        if not os.access(path, os.X_OK):
            sys.exit(f"soak: {path} is missing: build first (meson compile -C {args.build})")
    tmp = tempfile.mkdtemp(prefix="sdfd-soak-")
    soak = Soak(args, tools, tmp)
    try:
        soak.setup()
        code = soak.run()
    finally:
        if getattr(soak, "server", None) and soak.server.proc.poll() is None:
            soak.server.stop()
        shutil.rmtree(tmp, True)
    sys.exit(code)


if __name__ == "__main__":
    main()
