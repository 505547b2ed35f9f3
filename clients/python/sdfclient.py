"""sdfclient - Python client for sdfd (standard library + numpy only).

    import numpy as np, sdfclient
    c = sdfclient.Client("http://127.0.0.1:8080")
    c.meshes()                                   # [{'name': 'demo', 'triangles': 12288, ...}]
    r = c.query("demo", np.zeros((5, 3)), mode="gradient")
    r["distance"], r["gradient"]                 # float32 arrays (5,) and (5, 3)

    b = sdfclient.BinaryClient("127.0.0.1", 9090)
    r = b.query("demo", points, mode="closest")  # distance, closest, triangle
    rs = b.query_many([("demo", p1), ("demo", p2)])   # pipelined on one connection

    # the convolution-filtered field (docs/filtered.md); filter= takes its parameters
    r = c.query("demo", points, mode="filtered-gradient", filter={"samples": 32, "seed": 1})

    # baked volumes (docs/volumes.md): bake, wait, download, query
    job = c.bake("demo", volume="knot", resolution=64, order=1)
    c.wait(job)
    grid = c.download("knot", format="npy")      # float32 (64, 64, 64, 4)
    r = c.query_volume("knot", points, interpolation="trilinear", gradient=True)

Results are dicts of numpy arrays: "distance" always (the filtered value g in the filtered
modes); "gradient" (modes gradient and filtered-gradient); "closest" and "triangle" (mode
closest). Errors raise SdfError with the HTTP status, the error code (e.g. "ENOTFOUND") and
the server's message.

Client keeps one connection alive and opens a new one once the server has closed it (after
its --timeout of idleness). A request whose connection drops before its answer arrives is
sent once more only where that does no harm (queries, GET, PUT, DELETE); a bake is not, as it
would start a second job: its ConnectionError reaches the caller, and jobs() tells whether
it started.
"""
import http.client
import io
import json
import select
import socket
import struct
import time
import urllib.parse

import numpy as np

__all__ = ["Client", "BinaryClient", "SdfError"]

MODES = {"signed": 0, "distance": 1, "gradient": 2, "closest": 3, "filtered": 4,
         "filtered-gradient": 5}
SIGNS = {"auto": 0, "pseudonormal": 1, "winding": 2, "raycast": 3, "none": 4}
WORDS = {0: 1, 1: 1, 2: 4, 3: 5, 4: 1, 5: 4}
FILTER_KEYS = ("kernel", "cap", "a", "b", "samples", "min_samples", "medial", "grid", "unsigned",
               "allow_wide_bump", "sample_gradient", "seed", "smooth")
KERNELS = {"gaussian": 0, "bump": 1}
VOLUMES = {"sphere": 1, "box": 2, "mesh": 3}


class SdfError(Exception):
    """A request sdfd refused: .status (HTTP status), .code ("EINVAL" ...), .message."""

    def __init__(self, status, code, message):
        super().__init__(f"{status} {code}: {message}")
        self.status, self.code, self.message = status, code, message


def _points(points):
    p = np.ascontiguousarray(points, dtype=np.float32)
    if p.ndim == 1 and p.size % 3 == 0:
        p = p.reshape(-1, 3)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError("points must have shape (N, 3)")
    return p


def _filter(filter):
    f = dict(filter or {})
    unknown = set(f) - set(FILTER_KEYS)
    if unknown:
        raise ValueError(f"unknown filter parameters {sorted(unknown)} (known: {FILTER_KEYS})")
    return f


def _volume(smooth):
    """The one volume of a "smooth" dict: (kind, value)."""
    kinds = [k for k in VOLUMES if k in smooth]
    if len(kinds) != 1:
        raise ValueError('filter["smooth"] needs exactly one of "sphere", "box" or "mesh"')
    return kinds[0], smooth[kinds[0]]


def _url_filter(f):
    """Filter parameters as URL arguments (booleans as 1/0, the volume as smooth_*)."""
    out = {k: (int(v) if isinstance(v, bool) else v) for k, v in f.items() if k != "smooth"}
    if "smooth" in f:
        kind, value = _volume(f["smooth"])
        out["smooth_" + kind] = value if kind == "mesh" else ",".join(repr(float(x)) for x in value)
        for k in ("depth", "scale"):
            if k in f["smooth"]:
                out["smooth_" + k] = f["smooth"][k]
    return out


def _split_words(words, mode):
    """(N, W) uint32 words in the wire layout -> result dict."""
    out = {"distance": words[:, 0].view(np.float32).copy()}
    if mode in ("gradient", "filtered-gradient"):
        out["gradient"] = words[:, 1:4].copy().view(np.float32)
    if mode == "closest":
        out["closest"] = words[:, 1:4].copy().view(np.float32)
        out["triangle"] = words[:, 4].copy()
    return out


class Client:
    """HTTP client on one persistent connection (not thread-safe: one per thread)."""

    def __init__(self, url="http://127.0.0.1:8080", token=None, timeout=120):
        u = urllib.parse.urlsplit(url)
        self.host, self.port = u.hostname, u.port or 80
        self.token, self.timeout = token, timeout
        self._conn = None

    def close(self):
        if self._conn:
            self._conn.close()
            self._conn = None

    def _connection(self):
        """The kept-alive connection, or a new one if the server has closed it since (its
        --timeout for idle connections): an idle connection that reads as ready holds the
        server's end of it."""
        if self._conn is not None and self._conn.sock is not None:
            if select.select([self._conn.sock], [], [], 0)[0]:
                self.close()
        if self._conn is None:
            self._conn = http.client.HTTPConnection(self.host, self.port, timeout=self.timeout)
        return self._conn

    def _request(self, method, path, body=None, headers=None):
        headers = dict(headers or {})
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        # A request the connection dropped is sent once more only if sending it twice does no
        # harm: not a bake, which would start a second job when only its answer was lost.
        repeatable = method != "POST" or path.split("?")[0].endswith("/query")
        for attempt in (0, 1):
            conn = self._connection()
            try:
                conn.request(method, path, body=body, headers=headers)
                resp = conn.getresponse()
                data = resp.read()
                break
            except (http.client.RemoteDisconnected, ConnectionResetError, BrokenPipeError):
                self.close()
                if attempt or not repeatable:
                    raise
        if resp.getheader("Connection", "").lower() == "close":
            self.close()
        if resp.status >= 400:
            try:
                e = json.loads(data)["error"]
                raise SdfError(resp.status, e["code"], e["message"])
            except (ValueError, KeyError, TypeError):
                raise SdfError(resp.status, "EUNKNOWN", data[:200].decode("utf-8", "replace"))
        return resp, data

    def _json(self, method, path):
        return json.loads(self._request(method, path)[1])

    def health(self):
        return self._json("GET", "/healthz")

    def meshes(self):
        return self._json("GET", "/v1/meshes")["meshes"]

    def mesh(self, name):
        return self._json("GET", f"/v1/meshes/{name}")

    def upload(self, name, path, format=None):
        with open(path, "rb") as f:
            data = f.read()
        q = f"?format={format}" if format else ""
        return json.loads(self._request("PUT", f"/v1/meshes/{name}{q}", data,
                                        {"Content-Type": "application/octet-stream"})[1])

    def delete(self, name):
        self._request("DELETE", f"/v1/meshes/{name}")

    def metrics(self):
        return self._request("GET", "/metrics")[1].decode()

    def query(self, name, points, mode="signed", sign="auto", form="npy", filter=None):
        """Query points ((N, 3) array-like) in body form "npy", "octet" or "json"; `filter`
        holds the filtered modes' parameters (kernel, cap, a, b, samples, min_samples, medial,
        grid, unsigned, allow_wide_bump, sample_gradient, seed, smooth)."""
        p = _points(points)
        f = _filter(filter)
        path = f"/v1/meshes/{name}/query"
        if form == "json":
            req = {"points": p.tolist(), "mode": mode, "sign": sign}
            if f:
                req["filter"] = f
            body = json.dumps(req)
            _, data = self._request("POST", path, body, {"Content-Type": "application/json"})
            r = json.loads(data)
            out = {"distance": np.asarray(r["distance"], np.float32)}
            for k in ("gradient", "closest"):
                if k in r:
                    out[k] = np.asarray(r[k], np.float32).reshape(-1, 3)
            if "triangle" in r:
                out["triangle"] = np.asarray(r["triangle"], np.uint32)
            return out
        path += "?" + urllib.parse.urlencode({"mode": mode, "sign": sign, **_url_filter(f)})
        if form == "octet":
            _, data = self._request("POST", path, p.tobytes(),
                                    {"Content-Type": "application/octet-stream"})
            words = np.frombuffer(data, np.uint32).reshape(len(p), WORDS[MODES[mode]])
            return _split_words(words, mode)
        if form != "npy":
            raise ValueError("form must be npy, octet or json")
        buf = io.BytesIO()
        np.save(buf, p)
        _, data = self._request("POST", path, buf.getvalue(),
                                {"Content-Type": "application/x-npy"})
        a = np.load(io.BytesIO(data))
        if mode == "closest":  # a structured array: distance, closest (3,), triangle
            return {"distance": a["distance"], "closest": a["closest"], "triangle": a["triangle"]}
        if a.ndim == 1:
            return {"distance": a}
        return {"distance": a[:, 0].copy(), "gradient": a[:, 1:4].copy()}

    # ---- volumes (docs/volumes.md) ----

    def bake(self, name, volume=None, **params):
        """Start baking mesh `name` into a volume; returns the job (a dict with "id").
        params: bounds={"min": [...], "max": [...]}, margin, resolution (n or [n, m, k]),
        order (0 | 1), H, delta, field ("raw" | "filtered"), filter={...},
        encoding ("float32" | "packed32"), sign."""
        body = dict(params)
        if volume is not None:
            body["volume"] = volume
        _, data = self._request("POST", f"/v1/meshes/{name}/bake", json.dumps(body),
                                {"Content-Type": "application/json"})
        return json.loads(data)

    def job(self, job_id):
        return self._json("GET", f"/v1/jobs/{job_id}")

    def jobs(self):
        return self._json("GET", "/v1/jobs")["jobs"]

    def cancel(self, job_id):
        return self._json("DELETE", f"/v1/jobs/{job_id}")

    def wait(self, job, timeout=600, poll=0.05):
        """Poll a job (its id or the dict bake returned) until it ends; returns its final
        status, or raises SdfError if it failed or was canceled, TimeoutError on timeout."""
        job_id = job["id"] if isinstance(job, dict) else job
        deadline = time.monotonic() + timeout
        while True:
            s = self.job(job_id)
            if s["state"] == "done":
                return s
            if s["state"] in ("failed", "canceled"):
                e = s.get("error", {"code": "ECANCELED", "message": "the bake was canceled"})
                raise SdfError(409 if s["state"] == "canceled" else 500, e["code"], e["message"])
            if time.monotonic() > deadline:
                raise TimeoutError(f"job {job_id} still {s['state']} after {timeout} s")
            time.sleep(poll)

    def volumes(self):
        return self._json("GET", "/v1/volumes")["volumes"]

    def volume(self, name):
        return self._json("GET", f"/v1/volumes/{name}")

    def upload_volume(self, name, path_or_bytes):
        """Store an EXR volume (a download from this or another server) as `name`."""
        data = path_or_bytes
        if not isinstance(data, (bytes, bytearray)):
            with open(path_or_bytes, "rb") as f:
                data = f.read()
        return json.loads(self._request("PUT", f"/v1/volumes/{name}", data,
                                        {"Content-Type": "image/x-exr"})[1])

    def delete_volume(self, name):
        self._request("DELETE", f"/v1/volumes/{name}")

    def download(self, name, format="npy", path=None):
        """A volume's file bytes (format "exr", "npy" or "raw"), written to `path` if given;
        with format "npy" and no path, the numpy array itself."""
        _, data = self._request("GET", f"/v1/volumes/{name}/data?format={format}")
        if path is not None:
            with open(path, "wb") as f:
                f.write(data)
            return path
        return np.load(io.BytesIO(data)) if format == "npy" else data

    def query_volume(self, name, points, interpolation="trilinear", gradient=False, form="npy"):
        """Evaluate a baked volume at points: {"distance": (N,)} and with gradient=True also
        {"gradient": (N, 3)}."""
        p = _points(points)
        mode = "gradient" if gradient else "value"
        path = f"/v1/volumes/{name}/query"
        if form == "json":
            body = json.dumps({"points": p.tolist(), "mode": mode, "interpolation": interpolation})
            r = json.loads(self._request("POST", path, body, {"Content-Type": "application/json"})[1])
            out = {"distance": np.asarray(r["distance"], np.float32)}
            if gradient:
                out["gradient"] = np.asarray(r["gradient"], np.float32).reshape(-1, 3)
            return out
        path += "?" + urllib.parse.urlencode({"mode": mode, "interpolation": interpolation})
        if form == "octet":
            _, data = self._request("POST", path, p.tobytes(),
                                    {"Content-Type": "application/octet-stream"})
            words = np.frombuffer(data, np.uint32).reshape(len(p), 4 if gradient else 1)
            return _split_words(words, "gradient" if gradient else "signed")
        buf = io.BytesIO()
        np.save(buf, p)
        _, data = self._request("POST", path, buf.getvalue(), {"Content-Type": "application/x-npy"})
        a = np.load(io.BytesIO(data))
        return {"distance": a} if a.ndim == 1 else {"distance": a[:, 0].copy(),
                                                    "gradient": a[:, 1:4].copy()}


class BinaryClient:
    """Binary protocol client (proto/PROTOCOL.md) on one TCP connection."""

    HEADER = struct.Struct("<4sBBHII")

    def __init__(self, host="127.0.0.1", port=9090, timeout=120, token=None):
        """With `token`, the connection authenticates first (AUTH), as a server started with
        --token and --auth-queries requires before queries."""
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._next_id = 1
        if token is not None:
            self.auth(token)

    def auth(self, token):
        """AUTH: present the server's --token (a wrong one closes the connection)."""
        self._call(0x05, token.encode())

    def close(self):
        self.sock.close()

    def _send(self, type_, payload):
        rid = self._next_id
        self._next_id = (self._next_id + 1) & 0xFFFFFFFF or 1
        self.sock.sendall(self.HEADER.pack(b"SDFP", 1, type_, 0, rid, len(payload)) + payload)
        return rid

    def _recv_exact(self, n):
        chunks, got = [], 0
        while got < n:
            c = self.sock.recv(min(n - got, 1 << 20))
            if not c:
                raise ConnectionError("sdfd closed the connection")
            chunks.append(c)
            got += len(c)
        return b"".join(chunks)

    def _recv(self):
        magic, version, type_, _, rid, length = self.HEADER.unpack(self._recv_exact(16))
        if magic != b"SDFP" or version != 1:
            raise ConnectionError("not an sdfd binary protocol reply")
        payload = self._recv_exact(length)
        if type_ == 0x7F:
            status, n = struct.unpack_from("<HH", payload)
            code = payload[4:4 + n].decode()
            (m,) = struct.unpack_from("<H", payload, 4 + n)
            error = SdfError(status, code, payload[6 + n:6 + n + m].decode())
            if rid == 0:  # about the connection itself (PROTOCOL.md), which sdfd now closes
                self.close()
                raise error
            return rid, type_, error
        return rid, type_, payload

    def _call(self, type_, payload=b""):
        rid = self._send(type_, payload)
        got, t, p = self._recv()
        if got != rid:
            raise ConnectionError(f"reply to request {got}, expected {rid}")
        if isinstance(p, SdfError):
            raise p
        return t, p

    def hello(self):
        _, p = self._call(0x01, b"sdfclient.py")
        version, _, max_payload, max_points, n = struct.unpack_from("<HHIIH", p)
        return {"version": version, "max_payload": max_payload, "max_points": max_points,
                "server": p[14:14 + n].decode()}

    def meshes(self):
        _, p = self._call(0x02)
        (count,), off, out = struct.unpack_from("<I", p), 4, []
        for _ in range(count):
            (n,) = struct.unpack_from("<H", p, off)
            name = p[off + 2:off + 2 + n].decode()
            tris, closed, sign = struct.unpack_from("<QBB", p, off + 2 + n)
            off += 12 + n
            sign_name = {v: k for k, v in SIGNS.items()}.get(sign, str(sign))
            out.append({"name": name, "triangles": tris, "closed": bool(closed), "sign": sign_name})
        return out

    @staticmethod
    def _filter_block(filter):
        """The FILTER block of a filtered QUERY (PROTOCOL.md): 120 bytes, then a smoothing
        mesh's name padded to 4."""
        f = _filter(filter)
        flags = (1 if f.get("grid") else 0) | (2 if f.get("unsigned") else 0) \
            | (4 if f.get("allow_wide_bump") else 0) | (8 if f.get("sample_gradient") else 0)
        smooth = f.get("smooth") or {}
        volume, numbers, name = 0, [0.0] * 6, b""
        if smooth:
            kind, value = _volume(smooth)
            volume = VOLUMES[kind]
            if kind == "mesh":
                name = value.encode()
            else:
                numbers = [float(x) for x in value] + [0.0] * (6 - len(value))
        block = struct.pack("<BBBBIdddQdd6dIId", KERNELS[f.get("kernel", "gaussian")], flags,
                            volume, len(name), f.get("samples", 0), f.get("cap", 0.0),
                            f.get("a", 0.0), f.get("b", 0.0), f.get("seed", 0),
                            smooth.get("depth", 0.0), smooth.get("scale", 0.0), *numbers,
                            f.get("min_samples", 0), 0, f.get("medial", 0.0))
        return block + name + b"\0" * ((-len(name)) % 4)

    @classmethod
    def _query_payload(cls, name, points, mode, sign, filter=None):
        p = _points(points)
        nb = name.encode()
        pad = (-len(nb)) % 4
        block = cls._filter_block(filter) if mode.startswith("filtered") else b""
        return struct.pack("<BBHI", MODES[mode], SIGNS[sign], len(nb), len(p)) + nb + b"\0" * pad \
            + block + p.tobytes()

    @staticmethod
    def _result(payload, mode):
        m, w, _, count = struct.unpack_from("<BBHI", payload)
        words = np.frombuffer(payload, np.uint32, offset=8).reshape(count, w)
        return _split_words(words, mode)

    def query(self, name, points, mode="signed", sign="auto", filter=None):
        _, p = self._call(0x03, self._query_payload(name, points, mode, sign, filter))
        return self._result(p, mode)

    def query_volume(self, name, points, interpolation="trilinear", gradient=False):
        """VOLUME_QUERY: evaluate a baked volume; {"distance"} and with gradient=True
        {"gradient"} too."""
        p = _points(points)
        nb = name.encode()
        payload = struct.pack("<BBHI", 1 if gradient else 0,
                              {"trilinear": 0, "nearest": 1}[interpolation], len(nb), len(p)) \
            + nb + b"\0" * ((-len(nb)) % 4) + p.tobytes()
        _, r = self._call(0x04, payload)
        return self._result(r, "gradient" if gradient else "signed")

    def query_many(self, requests, mode="signed", sign="auto", window=32, filter=None):
        """Pipeline [(name, points), ...] with up to `window` requests in flight; replies may
        arrive in any order. Returns results (or SdfError objects) in request order."""
        ids, got = [], {}
        for name, points in requests:
            if len(ids) - len(got) >= window:
                self._collect(got, mode)
            ids.append(self._send(0x03, self._query_payload(name, points, mode, sign, filter)))
        while len(got) < len(ids):
            self._collect(got, mode)
        return [got[i] for i in ids]

    def _collect(self, got, mode):
        rid, _, p = self._recv()
        got[rid] = p if isinstance(p, SdfError) else self._result(p, mode)
