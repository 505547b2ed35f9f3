"""BinaryClient: sdfd's binary protocol (proto/PROTOCOL.md) on one TCP connection, with
pipelined queries (query_many) whose replies may come back in any order.

Queries only read, so one whose connection dies before its answer (a replica killed or
drained behind a load balancer, an idle connection the server closed) is sent once more on a
new connection; so is one that a server going away refuses with 503 EUNAVAILABLE, as a
draining sdfd does with the frames it reads after SIGTERM on connections already open."""
from __future__ import annotations

import collections
import socket
import ssl
import struct
import time
from typing import (Any, ClassVar, Deque, Dict, Iterable, List, Mapping, Optional, Set, Tuple,
                    Union)

import numpy as np
import numpy.typing as npt

from ._wire import (FRAMES, INTERPOLATIONS, KERNELS, MODES, SIGNS, VOLUMES, Interpolation, Mode,
                    Result, SdfError, Sign, _filter, _points, _split_words, _volume)


class _BrokenStream(ConnectionError):
    """A reply that is not sdfd's protocol, or answers no request sent: sending again would
    not help, so nothing is."""


# What says the connection died under a request, which may then go again on a new one.
_LOST = (ConnectionError, ssl.SSLEOFError, ssl.SSLZeroReturnError)
CONNECT_ATTEMPTS = 3  # a new connection's handshake, before a re-send gives up


class BinaryClient:
    """Binary protocol client (proto/PROTOCOL.md) on one TCP connection (one per thread).

    Results are dicts of numpy arrays (see Result); a refused request raises SdfError.

    QUERY and VOLUME_QUERY (query, query_many, query_volume) survive one lost connection:
    a request whose connection dies before its answer (EOF, reset), or that the server
    refuses as unavailable (503 EUNAVAILABLE: shutting down or still loading), is sent once
    more on a new connection to the same host and port (a load balancer picks a live
    replica), which repeats the constructor's TLS settings and AUTH (the token given to the
    constructor, or to the last auth() that succeeded) and then sends HELLO. Its handshake
    is tried up to CONNECT_ATTEMPTS times, as a balancer may still hand it to a replica that
    is going away; no request is sent on it before HELLO is answered. A request is re-sent at
    most once: if it is lost again, the call raises that ConnectionError (a refusal again
    raises, or in query_many returns, its SdfError). A timeout is not retried. A query on a
    connection known to be dead opens a new one first. hello(), meshes() and auth() use the
    connection as it is. `connects` counts the connections opened, `resent` the requests
    sent again."""

    HEADER: ClassVar[struct.Struct] = struct.Struct("<4sBBHII")
    """A frame's header: magic b"SDFP", version, type, flags, request id, payload length."""

    sock: socket.socket
    connects: int
    resent: int

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
        self._where, self._timeout, self._token = (host, port), timeout, token
        self._tls: Optional[ssl.SSLContext] = None
        if tls:
            self._tls = ssl.create_default_context(cafile=cafile)
            self._tls.minimum_version = ssl.TLSVersion.TLSv1_2
        self._closed = self._dead = False
        self.connects, self.resent = 1, 0
        self.sock = self._connect()
        self._next_id = 1
        if token is not None:
            self.auth(token)

    def _connect(self) -> socket.socket:
        """A new TCP (and with tls=True, TLS) connection to the server."""
        sock = socket.create_connection(self._where, timeout=self._timeout)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self._tls is not None:
            try:
                sock = self._tls.wrap_socket(sock, server_hostname=self._where[0])
            except BaseException:
                sock.close()
                raise
        return sock

    def _reconnect(self) -> None:
        """A new connection in place of the dead one: connect, AUTH (with a token), HELLO.
        One lost before HELLO is answered is tried again, CONNECT_ATTEMPTS times in all."""
        for attempt in range(CONNECT_ATTEMPTS):
            self._drop()
            try:
                self.sock = self._connect()
                self._dead = False
                if self._token is not None:
                    self._call(FRAMES["AUTH"], self._token.encode())
                self.hello()
                self.connects += 1
                return
            except _LOST as e:
                self._drop()
                if isinstance(e, _BrokenStream) or attempt + 1 == CONNECT_ATTEMPTS:
                    raise
                time.sleep(0.05 * 2 ** attempt)

    def _drop(self) -> None:
        """Forget the connection: what is unread on it can no longer be matched to requests."""
        self.sock.close()
        self._dead = True

    def auth(self, token: str) -> None:
        """AUTH: present the server's --token (a wrong one closes the connection); new
        connections present it too."""
        self._call(FRAMES["AUTH"], token.encode())
        self._token = token

    def close(self) -> None:
        """Close the connection; queries raise ConnectionError after it."""
        self._closed = True
        self._drop()

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
            raise _BrokenStream("not an sdfd binary protocol reply")
        payload = self._recv_exact(length)
        if type_ == FRAMES["ERROR"]:
            status, n = struct.unpack_from("<HH", payload)
            code = payload[4:4 + n].decode()
            (m,) = struct.unpack_from("<H", payload, 4 + n)
            error = SdfError(status, code, payload[6 + n:6 + n + m].decode())
            if rid == 0:  # about the connection itself (PROTOCOL.md), which sdfd now closes
                self._drop()
                raise error
            return rid, type_, error
        return rid, type_, payload

    def _call(self, type_: int, payload: bytes = b"") -> Tuple[int, bytes]:
        """Send one request and read its reply: (type, payload); an ERROR raises SdfError."""
        try:
            rid = self._send(type_, payload)
            got, t, p = self._recv()
        except _LOST:
            self._drop()
            raise
        if got != rid:
            self._drop()
            raise _BrokenStream(f"reply to request {got}, expected {rid}")
        if isinstance(p, SdfError):
            raise p
        return t, p

    def _ask(self, type_: int, payload: bytes) -> bytes:
        """One QUERY or VOLUME_QUERY, sent once more if lost (see the class): its reply's
        payload; a refusal raises SdfError."""
        p = self._exchange([(type_, payload)], 1)[0]
        if isinstance(p, SdfError):
            raise p
        return p

    def _exchange(self, frames: List[Tuple[int, bytes]],
                  window: int) -> List[Union[bytes, SdfError]]:
        """Send frames [(type, payload), ...] with up to `window` in flight; each reply's
        payload (or SdfError) in request order. A frame lost with its connection or refused
        as unavailable goes again, first, on the next connection, once (see the class)."""
        if self._closed:
            raise ConnectionError("the BinaryClient is closed")
        if window < 1:
            raise ValueError("window must be at least 1")
        out: Dict[int, Union[bytes, SdfError]] = {}
        todo: Deque[int] = collections.deque(range(len(frames)))  # indexes, re-sends first
        retried: Set[int] = set()
        while todo:
            if self._dead:
                self._reconnect()
            sent: Dict[int, int] = {}  # request id -> index, on this connection
            sending, moving = -1, False  # moving: the server refused as unavailable
            again: List[int] = []
            try:
                while todo or sent:
                    while todo and not moving and len(sent) < window:
                        sending = todo.popleft()
                        sent[self._send(*frames[sending])] = sending
                        sending = -1
                    if not sent:
                        break
                    rid, _, p = self._recv()
                    if rid not in sent:
                        raise _BrokenStream(f"reply to request {rid}, which was not sent")
                    i = sent.pop(rid)
                    if isinstance(p, SdfError) and p.code == "EUNAVAILABLE" \
                            and i not in retried:
                        again.append(i)
                        moving = True
                    else:
                        out[i] = p
            except _LOST as e:
                self._drop()
                lost = sorted(list(sent.values()) + ([sending] if sending >= 0 else []))
                if isinstance(e, _BrokenStream) or retried.intersection(lost):
                    raise
                again += lost
            except BaseException:
                self._drop()  # a timeout or an ERROR about the connection: unread replies
                raise
            if again:
                if not self._dead:
                    self._drop()
                retried.update(again)
                self.resent += len(again)
                todo.extendleft(sorted(again, reverse=True))
        return [out[i] for i in range(len(frames))]

    def hello(self) -> Dict[str, Any]:
        """HELLO: the server's protocol "version", "max_payload", "max_points" and "server"."""
        _, p = self._call(FRAMES["HELLO"], b"sdfclient.py")
        version, _, max_payload, max_points, n = struct.unpack_from("<HHIIH", p)
        return {"version": version, "max_payload": max_payload, "max_points": max_points,
                "server": p[14:14 + n].decode()}

    def meshes(self) -> List[Dict[str, Any]]:
        """LIST_MESHES: [{"name", "triangles", "closed", "sign"}, ...]."""
        _, p = self._call(FRAMES["LIST_MESHES"])
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
        p = self._ask(FRAMES["QUERY"], self._query_payload(name, points, mode, sign, filter))
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
        r = self._ask(FRAMES["VOLUME_QUERY"], payload)
        return self._result(r, "gradient" if gradient else "signed")

    def query_many(self, requests: Iterable[Tuple[str, npt.ArrayLike]], mode: Mode = "signed",
                   sign: Sign = "auto", window: int = 32,
                   filter: Optional[Mapping[str, Any]] = None) -> List[Union[Result, SdfError]]:
        """Pipeline [(name, points), ...] with up to `window` requests in flight; replies may
        arrive in any order. Returns results (or SdfError objects) in request order. Each
        request is sent once more if its connection dies first (see the class)."""
        frames = [(FRAMES["QUERY"], self._query_payload(name, points, mode, sign, filter))
                  for name, points in requests]
        return [p if isinstance(p, SdfError) else self._result(p, mode)
                for p in self._exchange(frames, window)]
