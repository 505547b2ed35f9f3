"""Start the real sdfd on free loopback ports for a test, and stop it.

Ports: sdfd is started with --http 127.0.0.1:0 --bin 127.0.0.1:0 and logs the ports the
kernel picked ("listening" events); the harness reads them from its JSON log. The log is
drained on a thread (a full pipe would block the server) and kept for assertions.
Paths come from meson: SDFD (the daemon), SDF_BENCH (sdf-bench), SDF_TEST_DATA. Also the
two binary-protocol frames tests write by hand (proto/PROTOCOL.md): a QUERY, and reading one
reply.

Importing it checks every HTTP answer the test then receives through http.client (the Python
client, urllib, hand-made requests) against docs/openapi.yaml (tests/api/apicheck.py): an
answer the document does not describe fails the request, and stop() fails as well."""
import json
import os
import pwd
import signal
import struct
import subprocess
import sys
import threading
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "api"))
import apicheck  # noqa: E402

apicheck.install()

SDFD = os.environ.get("SDFD", "build/server/sdfd")
SDF_BENCH = os.environ.get("SDF_BENCH", "build/tests/bench/sdf-bench")
DATA = os.environ.get("SDF_TEST_DATA", "tests/data")


class Server:
    def __init__(self, *args, wait_ready=True, user=None, prefix=()):
        """sdfd with args; as `user` (a name, with its primary group) when given, and run by
        the command `prefix` (which must exec sdfd, so that signals reach it) when given."""
        ids = {}
        if user:
            ids = {"user": user, "group": pwd.getpwnam(user).pw_gid, "extra_groups": []}
        self.proc = subprocess.Popen(
            [*prefix, SDFD, "--http", "127.0.0.1:0", "--bin", "127.0.0.1:0", *args],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **ids)
        self.logs, self.ports = [], {}
        self._ready = threading.Event()
        self._reader = threading.Thread(target=self._read_log, daemon=True)
        self._reader.start()
        if wait_ready and not self._ready.wait(60):
            self.stop()
            raise RuntimeError("sdfd did not become ready:\n" + "\n".join(map(str, self.logs)))

    def _read_log(self):
        for line in self.proc.stderr:
            try:
                entry = json.loads(line)
            except ValueError:
                entry = {"unparsed": line.decode(errors="replace")}
            self.logs.append(entry)
            if entry.get("event") == "listening":
                self.ports[entry["proto"]] = entry["port"]
            if entry.get("event") == "ready":
                self._ready.set()

    @property
    def url(self):
        return f"http://127.0.0.1:{self.ports['http']}"

    @property
    def bin_port(self):
        return self.ports["binary"]

    def stop(self, sig=signal.SIGTERM, timeout=60):
        """Signal the server and wait; returns its exit code. A sanitizer report anywhere in
        its log (the sanitizer builds: a leak, an overflow, undefined behaviour, a race), or
        an answer outside docs/openapi.yaml since the last stop, fails the test that ran it,
        whatever the code."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait()
        self._reader.join(5)
        reports = self.sanitizer_reports()
        if reports:
            raise AssertionError("sdfd's sanitizer reported:\n" + "".join(reports[:80]))
        outside = apicheck.take_violations()
        if outside:
            raise AssertionError("answers outside docs/openapi.yaml:\n" + "\n".join(outside))
        return code

    def sanitizer_reports(self):
        """Its log's lines from the first sanitizer report on (they are not JSON)."""
        lines = [e["unparsed"] for e in self.logs if "unparsed" in e]
        for i, line in enumerate(lines):
            if "Sanitizer" in line or "runtime error" in line:
                return lines[i:]
        return []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


BIN_HEADER = struct.Struct("<4sBBHII")  # magic, version, type, flags, request id, length


def bin_query(rid, points, name=b"demo", mode=0):
    """A binary QUERY frame of float32 points (bytes, or an array of shape (N, 3))."""
    data = points if isinstance(points, bytes) else points.tobytes()
    payload = struct.pack("<BBHI", mode, 0, len(name), len(data) // 12) + name + \
        b"\0" * (-len(name) % 4) + data
    return BIN_HEADER.pack(b"SDFP", 1, 3, 0, rid, len(payload)) + payload


def recv_exact(sock, n):
    """n bytes from sock; ConnectionError if the stream ends first."""
    out = b""
    while len(out) < n:
        chunk = sock.recv(n - len(out))
        if not chunk:
            raise ConnectionError("the connection ended")
        out += chunk
    return out


def recv_frame(sock):
    """(type, request id, payload) of the next frame; ConnectionError at the end of stream."""
    _, _, type_, _, rid, length = BIN_HEADER.unpack(recv_exact(sock, 16))
    return type_, rid, recv_exact(sock, length)


def same_bits(a, b):
    """Are a and b the same float32 array, bit for bit?"""
    a, b = np.ascontiguousarray(a, np.float32), np.ascontiguousarray(b, np.float32)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def wait_until(predicate, timeout=10.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return False


def metric(text, name, labels=None):
    """Value of one Prometheus sample from /metrics text."""
    for line in text.splitlines():
        if line.startswith("#"):
            continue
        key, _, value = line.rpartition(" ")
        if key == (f"{name}{{{labels}}}" if labels else name):
            return float(value)
    return None
