"""Client: sdfd's HTTP API (docs/api.md, docs/volumes.md) on one kept-alive connection.

It opens a new connection once the server has closed the old one (after its --timeout of
idleness). A request whose connection drops before its answer arrives is sent once more only
where that does no harm (queries, GET, PUT, DELETE); a bake is not, as it would start a second
job: its ConnectionError reaches the caller, and jobs() tells whether it started."""
from __future__ import annotations

import http.client
import io
import json
import os
import select
import ssl
import time
import urllib.parse
from typing import Any, Dict, Iterable, List, Literal, Mapping, Optional, Tuple, TypeVar, Union, \
    cast, overload

import numpy as np
import numpy.typing as npt

from ._wire import (MODES, WORDS, Form, Interpolation, Mode, Op, Result, SdfError, Sign, _filter,
                    _ops, _points, _split_words, _url_filter)

_Path = TypeVar("_Path", str, "os.PathLike[str]")


def _tls_context(cafile: Optional[str]) -> ssl.SSLContext:
    """A client context that verifies the server against `cafile` (or the system's CAs)
    and its host name, TLS 1.2 or later, as sdfd accepts."""
    ctx = ssl.create_default_context(cafile=cafile)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    return ctx


def _object(data: Union[str, bytes]) -> Dict[str, Any]:
    """A JSON object sdfd answered (its API's answers are objects)."""
    return cast(Dict[str, Any], json.loads(data))


def _ply_arrays(data: bytes) -> Dict[str, npt.NDArray[Any]]:
    """The arrays of a binary PLY as sdfd writes it (float xyz, then 3-index faces)."""
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").split("\n")
    nv = next(int(h.split()[2]) for h in header if h.startswith("element vertex"))
    nt = next(int(h.split()[2]) for h in header if h.startswith("element face"))
    vertices = np.frombuffer(data, "<f4", 3 * nv, end).reshape(nv, 3)
    faces = np.frombuffer(data, np.dtype([("n", "u1"), ("i", "<u4", (3,))]), nt, end + 12 * nv)
    return {"vertices": vertices.copy(), "triangles": faces["i"].astype(np.uint32)}


class Client:
    """HTTP client on one persistent connection (not thread-safe: one per thread).

    Results are dicts of numpy arrays (see Result); a refused request raises SdfError."""

    host: str
    port: int
    token: Optional[str]
    timeout: float

    def __init__(self, url: str = "http://127.0.0.1:8080", token: Optional[str] = None,
                 timeout: float = 120, cafile: Optional[str] = None) -> None:
        """Talk to the sdfd at `url` ("http://HOST:PORT", or "https://HOST:PORT" for a
        server started with --tls-cert); `token` is sent as a Bearer token (the server's
        --token); `timeout` in seconds bounds each socket operation. With https, the
        server's certificate is verified against `cafile` (PEM), or the system's CAs when
        None, and must name HOST. Nothing connects until the first request."""
        u = urllib.parse.urlsplit(url)
        if u.scheme not in ("http", "https") or not u.hostname:
            raise ValueError(f"url {url!r}: expected http://HOST:PORT or https://HOST:PORT")
        if cafile is not None and u.scheme != "https":
            raise ValueError("cafile is for https:// URLs")
        self.host, self.port = u.hostname, u.port or (443 if u.scheme == "https" else 80)
        self.token, self.timeout = token, timeout
        self._tls = _tls_context(cafile) if u.scheme == "https" else None
        self._conn: Optional[http.client.HTTPConnection] = None

    def close(self) -> None:
        """Close the connection (the next request opens a new one)."""
        if self._conn:
            self._conn.close()
            self._conn = None

    def _connection(self) -> http.client.HTTPConnection:
        """The kept-alive connection, or a new one if the server has closed it since (its
        --timeout for idle connections): an idle connection that reads as ready holds the
        server's end of it."""
        if self._conn is not None and self._conn.sock is not None:
            if select.select([self._conn.sock], [], [], 0)[0]:
                self.close()
        if self._conn is None:
            if self._tls is not None:
                self._conn = http.client.HTTPSConnection(self.host, self.port,
                                                         timeout=self.timeout, context=self._tls)
            else:
                self._conn = http.client.HTTPConnection(self.host, self.port,
                                                        timeout=self.timeout)
        return self._conn

    def _request(self, method: str, path: str, body: Optional[Union[str, bytes]] = None,
                 headers: Optional[Mapping[str, str]] = None
                 ) -> Tuple[http.client.HTTPResponse, bytes]:
        """Send one request; its response and body, or SdfError for a status >= 400."""
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

    def _json(self, method: str, path: str) -> Dict[str, Any]:
        return _object(self._request(method, path)[1])

    def health(self) -> Dict[str, Any]:
        """GET /healthz: the server's liveness answer."""
        return self._json("GET", "/healthz")

    def meshes(self) -> List[Dict[str, Any]]:
        """The loaded meshes: [{"name", "triangles", ...}, ...]."""
        return cast(List[Dict[str, Any]], self._json("GET", "/v1/meshes")["meshes"])

    def mesh(self, name: str) -> Dict[str, Any]:
        """One mesh's description (triangles, bounds, closed, sign ...)."""
        return self._json("GET", f"/v1/meshes/{name}")

    def upload(self, name: str, path: Union[str, os.PathLike[str]],
               format: Optional[str] = None) -> Dict[str, Any]:
        """Store the mesh file at `path` as `name` (needs the token); `format` ("obj", "ply",
        "stl", "off") where the server cannot tell it from the bytes. Returns its description."""
        with open(path, "rb") as f:
            data = f.read()
        q = f"?format={format}" if format else ""
        return _object(self._request("PUT", f"/v1/meshes/{name}{q}", data,
                                     {"Content-Type": "application/octet-stream"})[1])

    def upload_arrays(self, name: str, vertices: npt.ArrayLike,
                      faces: npt.ArrayLike) -> Dict[str, Any]:
        """Store the mesh of `vertices` ((V, 3) numbers) and `faces` ((F, 3) integer indices
        from 0) as `name` (needs the token), sent as an npz. Returns its description."""
        v = np.asarray(vertices)
        f = np.asarray(faces)
        if v.ndim != 2 or v.shape[1:] != (3,) or f.ndim != 2 or f.shape[1:] != (3,):
            raise ValueError("vertices must have shape (V, 3) and faces (F, 3), not "
                             f"{v.shape} and {f.shape}")
        if not np.issubdtype(f.dtype, np.integer):
            raise ValueError(f"faces must be integers, not {f.dtype}")
        buf = io.BytesIO()  # little-endian, as the server reads them
        np.savez(buf, vertices=v.astype("<f8" if v.dtype == np.float64 else "<f4"),
                 faces=f.astype(f.dtype.newbyteorder("<")))
        return _object(self._request("PUT", f"/v1/meshes/{name}?format=npz", buf.getvalue(),
                                     {"Content-Type": "application/octet-stream"})[1])

    def delete(self, name: str) -> None:
        """Unload mesh `name` (needs the token)."""
        self._request("DELETE", f"/v1/meshes/{name}")

    def metrics(self) -> str:
        """GET /metrics: the Prometheus text."""
        return self._request("GET", "/metrics")[1].decode()

    def query(self, name: str, points: npt.ArrayLike, mode: Mode = "signed", sign: Sign = "auto",
              form: Form = "npy", filter: Optional[Mapping[str, Any]] = None) -> Result:
        """Query points ((N, 3) array-like) in body form "npy", "octet" or "json"; `filter`
        holds the filtered modes' parameters (kernel, cap, a, b, samples, min_samples, medial,
        grid, unsigned, allow_wide_bump, sample_gradient, seed, smooth)."""
        p = _points(points)
        f = _filter(filter)
        path = f"/v1/meshes/{name}/query"
        if form == "json":
            req: Dict[str, Any] = {"points": p.tolist(), "mode": mode, "sign": sign}
            if f:
                req["filter"] = f
            body = json.dumps(req)
            _, data = self._request("POST", path, body, {"Content-Type": "application/json"})
            r = json.loads(data)
            out: Result = {"distance": np.asarray(r["distance"], np.float32)}
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

    # ---- slices (docs/api.md, Slices) ----

    def slice(self, name: str, volume: bool = False, format: str = "png",
              filter: Optional[Mapping[str, Any]] = None, **args: Any) -> Dict[str, Any]:
        """GET /v1/meshes/{name}/slice.png (or, with volume=True, the volume's): a plane of
        the field. `args` are the route's URL arguments: axis, at, normal, origin, bounds
        (sequences are sent as x,y,z), size, mode, sign, interpolation, step; `filter` the
        filtered mode's parameters. Returns {"format", "bytes", "width", "height", "first",
        "right", "down", "range", "step"}: pixel (i, j) is centred at first + i * right +
        j * down; with format="npy" also "values", float32 (height, width)."""
        if format not in ("png", "npy"):
            raise ValueError("format must be png or npy")
        query: Dict[str, str] = {}
        for k, v in args.items():
            if v is not None:
                query[k] = ",".join(repr(float(x)) for x in v) if isinstance(
                    v, (list, tuple, np.ndarray)) else str(v)
        query.update(_url_filter(_filter(filter)))
        if format != "png":
            query["format"] = format
        kind = "volumes" if volume else "meshes"
        q = "?" + urllib.parse.urlencode(query) if query else ""
        resp, data = self._request("GET", f"/v1/{kind}/{name}/slice.png{q}")

        def numbers(h: str) -> List[float]:
            return [float(x) for x in (resp.getheader("X-SDF-Slice-" + h) or "").split(",")]
        width, height = (int(x) for x in numbers("Size"))
        out: Dict[str, Any] = {
            "format": format, "bytes": data, "width": width, "height": height,
            "first": np.array(numbers("First")), "right": np.array(numbers("Right")),
            "down": np.array(numbers("Down")), "range": tuple(numbers("Range")),
            "step": numbers("Step")[0]}
        if format == "npy":
            out["values"] = np.load(io.BytesIO(data))
        return out

    # ---- volumes (docs/volumes.md) ----

    def bake(self, name: str, volume: Optional[str] = None, **params: Any) -> Dict[str, Any]:
        """Start baking mesh `name` into a volume; returns the job (a dict with "id").
        params: bounds={"min": [...], "max": [...]}, margin, resolution (n or [n, m, k]),
        order (0 | 1), H, delta, field ("raw" | "filtered"), filter={...},
        encoding ("float32" | "packed32"), sign; and field operations applied to the baked
        grid before it is stored: ops (as volume_ops's), solver, iterations, band, strict."""
        body = dict(params)
        if volume is not None:
            body["volume"] = volume
        if "ops" in body:
            body["ops"] = _ops(body["ops"])
        _, data = self._request("POST", f"/v1/meshes/{name}/bake", json.dumps(body),
                                {"Content-Type": "application/json"})
        return _object(data)

    def volume_ops(self, name: str, ops: Iterable[Op], volume: Optional[str] = None,
                   **params: Any) -> Dict[str, Any]:
        """Start field operations on volume `name` (POST /v1/volumes/{name}/ops, docs/api.md):
        `ops` in order, each {"round": 0.05} or ("round", 0.05) (redistance, offset, round,
        fillet, smooth); the result is stored as `volume` (the server's default when None).
        params: solver ("sussman" | "sweep" | "exact"), iterations, band, strict. Returns the job, as
        bake does ("kind": "ops"; once done, its "caveats" and "warning"): wait() for it."""
        body: Dict[str, Any] = dict(params, ops=_ops(ops))
        if volume is not None:
            body["volume"] = volume
        _, data = self._request("POST", f"/v1/volumes/{name}/ops", json.dumps(body),
                                {"Content-Type": "application/json"})
        return _object(data)

    def job(self, job_id: str) -> Dict[str, Any]:
        """A bake job's status: "state" (queued, running, done, failed, canceled) and more."""
        return self._json("GET", f"/v1/jobs/{job_id}")

    def jobs(self) -> List[Dict[str, Any]]:
        """Every job the server remembers, as job() describes each."""
        return cast(List[Dict[str, Any]], self._json("GET", "/v1/jobs")["jobs"])

    def cancel(self, job_id: str) -> Dict[str, Any]:
        """Cancel a queued or running job, or forget an ended one; returns its status."""
        return self._json("DELETE", f"/v1/jobs/{job_id}")

    def wait(self, job: Union[str, Mapping[str, Any]], timeout: float = 600,
             poll: float = 0.05) -> Dict[str, Any]:
        """Poll a job (its id or the dict bake returned) until it ends; returns its final
        status, or raises SdfError if it failed or was canceled, TimeoutError on timeout."""
        job_id = job["id"] if isinstance(job, Mapping) else job
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

    def volumes(self) -> List[Dict[str, Any]]:
        """The stored volumes' descriptions."""
        return cast(List[Dict[str, Any]], self._json("GET", "/v1/volumes")["volumes"])

    def volume(self, name: str) -> Dict[str, Any]:
        """One volume's description (resolution, bounds, order, encoding ...)."""
        return self._json("GET", f"/v1/volumes/{name}")

    def upload_volume(self, name: str,
                      path_or_bytes: Union[bytes, bytearray, str, os.PathLike[str]]
                      ) -> Dict[str, Any]:
        """Store an EXR volume (a download from this or another server) as `name`."""
        if isinstance(path_or_bytes, (bytes, bytearray)):
            data = bytes(path_or_bytes)
        else:
            with open(path_or_bytes, "rb") as f:
                data = f.read()
        return _object(self._request("PUT", f"/v1/volumes/{name}", data,
                                     {"Content-Type": "image/x-exr"})[1])

    def delete_volume(self, name: str) -> None:
        """Delete stored volume `name` (needs the token)."""
        self._request("DELETE", f"/v1/volumes/{name}")

    @overload
    def download(self, name: str, format: Literal["npy"] = ..., path: None = ...
                 ) -> npt.NDArray[Any]: ...

    @overload
    def download(self, name: str, format: Literal["exr", "raw"], path: None = ...) -> bytes: ...

    @overload
    def download(self, name: str, format: str, path: None = ...
                 ) -> Union[npt.NDArray[Any], bytes]: ...

    @overload
    def download(self, name: str, format: str, path: _Path) -> _Path: ...

    @overload
    def download(self, name: str, *, path: _Path) -> _Path: ...

    def download(self, name: str, format: str = "npy",
                 path: Optional[Union[str, os.PathLike[str]]] = None
                 ) -> Union[npt.NDArray[Any], bytes, str, os.PathLike[str]]:
        """A volume's file bytes (format "exr", "npy" or "raw"), written to `path` if given
        (which it returns); with format "npy" and no path, the numpy array itself."""
        _, data = self._request("GET", f"/v1/volumes/{name}/data?format={format}")
        if path is not None:
            with open(path, "wb") as f:
                f.write(data)
            return path
        return cast(npt.NDArray[Any], np.load(io.BytesIO(data))) if format == "npy" else data

    def extract_mesh(self, name: str, iso: float = 0.0, cap: bool = False,
                     format: Optional[str] = None,
                     path: Optional[Union[str, os.PathLike[str]]] = None,
                     mesh: Optional[str] = None, method: str = "auto") -> Any:
        """Volume `name`'s surface at `iso` (GET /v1/volumes/{name}/mesh, docs/api.md):
        closed and manifold where it stays inside the grid, and closed where it leaves it
        too with `cap`; `method` "marching_cubes", "dual_contouring" (sharp edges kept) or
        "auto" (dual contouring for first-order volumes). With `mesh`, stored on the server as that mesh (POST; returns its
        report); with `format` ("ply", "obj", "stl", "off") or `path` (format from its
        extension), the file's bytes (written to `path`, which is returned); else the arrays
        {"vertices": float32 (V, 3), "triangles": uint32 (T, 3)}."""
        if mesh is not None:
            body = {"mesh": mesh, "iso": iso, "cap": cap, "method": method}
            return _object(self._request("POST", f"/v1/volumes/{name}/mesh", json.dumps(body),
                                         {"Content-Type": "application/json"})[1])
        if format is None and path is not None:
            format = os.fspath(path).rsplit(".", 1)[-1].lower()
        q = urllib.parse.urlencode({"format": format or "ply", "iso": repr(float(iso)),
                                    "cap": "true" if cap else "false", "method": method})
        _, data = self._request("GET", f"/v1/volumes/{name}/mesh?{q}")
        if path is not None:
            with open(path, "wb") as f:
                f.write(data)
            return path
        return data if format is not None else _ply_arrays(data)

    def query_volume(self, name: str, points: npt.ArrayLike,
                     interpolation: Interpolation = "default", gradient: bool = False,
                     form: Form = "npy") -> Result:
        """Evaluate a baked volume at points: {"distance": (N,)} and with gradient=True also
        {"gradient": (N, 3)}. `interpolation`: "default" (hermite on first-order volumes,
        trilinear on zero-order ones; the server's default, so not sent), "trilinear",
        "nearest" or "hermite" (first order only)."""
        p = _points(points)
        mode = "gradient" if gradient else "value"
        path = f"/v1/volumes/{name}/query"
        args = {"mode": mode}
        if interpolation != "default":
            args["interpolation"] = interpolation
        if form == "json":
            body = json.dumps({"points": p.tolist(), **args})
            r = json.loads(self._request("POST", path, body, {"Content-Type": "application/json"})[1])
            out: Result = {"distance": np.asarray(r["distance"], np.float32)}
            if gradient:
                out["gradient"] = np.asarray(r["gradient"], np.float32).reshape(-1, 3)
            return out
        path += "?" + urllib.parse.urlencode(args)
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
