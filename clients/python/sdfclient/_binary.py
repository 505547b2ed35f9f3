"""BinaryClient: sdfd's binary protocol (proto/PROTOCOL.md) on one TCP connection, with
pipelined queries (query_many) whose replies may come back in any order."""
from __future__ import annotations

import socket
import ssl
import struct
from typing import Any, ClassVar, Dict, Iterable, List, Mapping, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._wire import (INTERPOLATIONS, KERNELS, MODES, SIGNS, VOLUMES, Interpolation, Mode, Result,
                    SdfError, Sign, _filter, _points, _split_words, _volume)


class BinaryClient:
    """Binary protocol client (proto/PROTOCOL.md) on one TCP connection (one per thread).

    Results are dicts of numpy arrays (see Result); a refused request raises SdfError."""

    HEADER: ClassVar[struct.Struct] = struct.Struct("<4sBBHII")
    """A frame's header: magic b"SDFP", version, type, flags, request id, payload length."""

    sock: socket.socket

    def __init__(self, host: str = "127.0.0.1", port: int = 9090, timeout: Optional[float] = 120,
                 token: Optional[str] = None, tls: bool = False,
                 cafile: Optional[str] = None) -> None:
        """Connect to sdfd's binary listener; `timeout` in seconds bounds each socket
        operation. With `token`, the connection authenticates first (AUTH), as a server
        started with --token and --auth-queries requires before queries. With `tls` (a
        server started with --bin-tls), the frames travel in TLS 1.2 or later, the server's
        certificate verified against `cafile` (PEM), or the system's CAs when None, and
        required to name `host`."""
        if cafile is not None and not tls:
            raise ValueError("cafile is for tls=True")
        sock = socket.create_connection((host, port), timeout=timeout)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if tls:
            ctx = ssl.create_default_context(cafile=cafile)
            ctx.minimum_version = ssl.TLSVersion.TLSv1_2
            try:
                sock = ctx.wrap_socket(sock, server_hostname=host)
            except BaseException:
                sock.close()
                raise
        self.sock = sock
        self._next_id = 1
        if token is not None:
            self.auth(token)

    def auth(self, token: str) -> None:
        """AUTH: present the server's --token (a wrong one closes the connection)."""
        self._call(0x05, token.encode())

    def close(self) -> None:
        """Close the connection."""
        self.sock.close()

    def _send(self, type_: int, payload: bytes) -> int:
        """Send one frame; its request id."""
        rid = self._next_id
        self._next_id = (self._next_id + 1) & 0xFFFFFFFF or 1
        self.sock.sendall(self.HEADER.pack(b"SDFP", 1, type_, 0, rid, len(payload)) + payload)
        return rid

    def _recv_exact(self, n: int) -> bytes:
        chunks, got = [], 0
        while got < n:
            c = self.sock.recv(min(n - got, 1 << 20))
            if not c:
                raise ConnectionError("sdfd closed the connection")
            chunks.append(c)
            got += len(c)
        return b"".join(chunks)

    def _recv(self) -> Tuple[int, int, Union[bytes, SdfError]]:
        """One reply frame: (request id, type, payload or the SdfError an ERROR frame holds)."""
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

    def _call(self, type_: int, payload: bytes = b"") -> Tuple[int, bytes]:
        """Send one request and read its reply: (type, payload); an ERROR raises SdfError."""
        rid = self._send(type_, payload)
        got, t, p = self._recv()
        if got != rid:
            raise ConnectionError(f"reply to request {got}, expected {rid}")
        if isinstance(p, SdfError):
            raise p
        return t, p

    def hello(self) -> Dict[str, Any]:
        """HELLO: the server's protocol "version", "max_payload", "max_points" and "server"."""
        _, p = self._call(0x01, b"sdfclient.py")
        version, _, max_payload, max_points, n = struct.unpack_from("<HHIIH", p)
        return {"version": version, "max_payload": max_payload, "max_points": max_points,
                "server": p[14:14 + n].decode()}

    def meshes(self) -> List[Dict[str, Any]]:
        """LIST_MESHES: [{"name", "triangles", "closed", "sign"}, ...]."""
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
    def _filter_block(filter: Optional[Mapping[str, Any]]) -> bytes:
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
    def _query_payload(cls, name: str, points: npt.ArrayLike, mode: Mode, sign: Sign,
                       filter: Optional[Mapping[str, Any]] = None) -> bytes:
        """A QUERY payload: header, padded mesh name, FILTER block (filtered modes), points."""
        p = _points(points)
        nb = name.encode()
        pad = (-len(nb)) % 4
        block = cls._filter_block(filter) if mode.startswith("filtered") else b""
        return struct.pack("<BBHI", MODES[mode], SIGNS[sign], len(nb), len(p)) + nb + b"\0" * pad \
            + block + p.tobytes()

    @staticmethod
    def _result(payload: bytes, mode: str) -> Result:
        """A RESULT payload as the result dict of `mode`."""
        m, w, _, count = struct.unpack_from("<BBHI", payload)
        words = np.frombuffer(payload, np.uint32, offset=8).reshape(count, w)
        return _split_words(words, mode)

    def query(self, name: str, points: npt.ArrayLike, mode: Mode = "signed", sign: Sign = "auto",
              filter: Optional[Mapping[str, Any]] = None) -> Result:
        """QUERY: points ((N, 3) array-like) against mesh `name`; `filter` as Client.query's."""
        _, p = self._call(0x03, self._query_payload(name, points, mode, sign, filter))
        return self._result(p, mode)

    def query_volume(self, name: str, points: npt.ArrayLike,
                     interpolation: Interpolation = "default", gradient: bool = False) -> Result:
        """VOLUME_QUERY: evaluate a baked volume; {"distance"} and with gradient=True
        {"gradient"} too. `interpolation` as Client.query_volume's."""
        p = _points(points)
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {sorted(INTERPOLATIONS)}, "
                             f"not {interpolation!r}")
        nb = name.encode()
        payload = struct.pack("<BBHI", 1 if gradient else 0, INTERPOLATIONS[interpolation],
                              len(nb), len(p)) \
            + nb + b"\0" * ((-len(nb)) % 4) + p.tobytes()
        _, r = self._call(0x04, payload)
        return self._result(r, "gradient" if gradient else "signed")

    def query_many(self, requests: Iterable[Tuple[str, npt.ArrayLike]], mode: Mode = "signed",
                   sign: Sign = "auto", window: int = 32,
                   filter: Optional[Mapping[str, Any]] = None) -> List[Union[Result, SdfError]]:
        """Pipeline [(name, points), ...] with up to `window` requests in flight; replies may
        arrive in any order. Returns results (or SdfError objects) in request order."""
        ids: List[int] = []
        got: Dict[int, Union[Result, SdfError]] = {}
        for name, points in requests:
            if len(ids) - len(got) >= window:
                self._collect(got, mode)
            ids.append(self._send(0x03, self._query_payload(name, points, mode, sign, filter)))
        while len(got) < len(ids):
            self._collect(got, mode)
        return [got[i] for i in ids]

    def _collect(self, got: Dict[int, Union[Result, SdfError]], mode: str) -> None:
        """Read one reply into `got` by its request id."""
        rid, _, p = self._recv()
        got[rid] = p if isinstance(p, SdfError) else self._result(p, mode)
