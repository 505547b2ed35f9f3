"""sdfd against clients that hold its connections without doing their share (issue 34):
  - slow-loris: clients that send one byte a second, on HTTP (in the headers and in the
    body) and on the binary protocol;
  - a flood: up to 1,000 HTTP and 1,000 binary connections that never send a byte, as many
    as the descriptor limit lets this process and sdfd hold (the soft limit is raised to the
    hard one first; the count used is printed);
  - a binary client that sends queries and never reads the replies: the server stops reading
    it (its sends stall, the server's memory stays bounded) and closes it.
Each such connection must be cut off within --timeout (2 s here, plus the server's check
interval), and meanwhile other clients' small queries must keep their latency: the median
during the attack within LATENCY_FACTOR of the median measured idle just before it, on both
protocols. The flood also checks that the server's descriptors go back to what they were.

Standard library and the harness only; the sockets are raw so that the test, not a client
library, decides what is sent and when."""
import http.client
import os
import resource
import selectors
import socket
import statistics
import struct
import sys
import threading
import time
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from harness import Server, bin_query, recv_frame, wait_until  # noqa: E402

TIMEOUT = 2          # --timeout of the servers here
SLACK = 1.6          # the HTTP watch looks 4 times a second, the binary loop once a second
# The sanitizer builds' instrumented locks and event loops cost more next to the client's own
# fixed cost per query, so there the bound is looser.
SANITIZED = os.environ.get("SDF_SANITIZE", "none") != "none"
LATENCY_FACTOR = 4.0 if SANITIZED else 2.0
FLOOD_MOST = 1000
# Descriptors a process needs besides the flood's: sdfd's listeners, epoll, eventfds, files
# and logs; the test's probes, pipes and Python's own. Both hold 2 x FLOOD of the flood.
FD_RESERVE = 128


def flood_size():
    """Raise the descriptor soft limit to the hard one (sdfd inherits it) and size the
    flood to what both processes can then hold: a connection a port each, per process."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != hard:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
        soft = hard
    if soft == resource.RLIM_INFINITY:
        return FLOOD_MOST, soft, hard
    return min(FLOOD_MOST, (soft - FD_RESERVE) // 2), soft, hard


FLOOD, FD_SOFT, FD_HARD = flood_size()


def query_frame(rid, n=1, mode=0, name=b"demo"):
    return bin_query(rid, struct.pack("<%df" % (3 * n), *([0.25] * (3 * n))), name, mode)


def open_fds(pid):
    return len(os.listdir(f"/proc/{pid}/fd"))


def rss_bytes(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


class Prober:
    """Sequential small queries, one HTTP (octet-stream, keep-alive) and one binary QUERY
    each round, timed; medians in seconds."""

    BODY = struct.pack("<3f", 0.25, 0.25, 0.25)

    def __init__(self, server):
        self.server = server
        self.http = http.client.HTTPConnection("127.0.0.1", server.ports["http"], timeout=30)
        self.connect_binary()
        self.rid = 0

    def connect_binary(self):
        self.bin = socket.create_connection(("127.0.0.1", self.server.bin_port), timeout=30)
        self.bin.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def one(self):
        try:
            return self.timed()
        except OSError:
            # The probes idle while a test waits (slowly, in a sanitizer build), and sdfd
            # closes an HTTP connection idle for --timeout, as it should: connect again.
            self.close()
            self.connect_binary()
            return self.timed()

    def timed(self):
        t0 = time.perf_counter()
        self.http.request("POST", "/v1/meshes/demo/query", self.BODY,
                          {"Content-Type": "application/octet-stream"})
        r = self.http.getresponse()
        r.read()
        t1 = time.perf_counter()
        self.rid += 1
        self.bin.sendall(query_frame(self.rid))
        type_, rid, _ = recv_frame(self.bin)
        t2 = time.perf_counter()
        if r.status != 200 or type_ != 0x83 or rid != self.rid:
            raise AssertionError(f"probe query failed: HTTP {r.status}, frame type {type_:#x}")
        return t1 - t0, t2 - t1

    def medians(self, seconds):
        http_s, bin_s = [], []
        end = time.time() + seconds
        while time.time() < end:
            h, b = self.one()
            http_s.append(h)
            bin_s.append(b)
        return statistics.median(http_s), statistics.median(bin_s), len(http_s)

    def close(self):
        self.http.close()
        self.bin.close()


class Attack(threading.Thread):
    """Runs `step(attack)` until stopped; keeps how long each attacking connection lived
    from its start until the server cut it off (`lived`), and anything unexpected."""

    def __init__(self, step):
        super().__init__(daemon=True)
        self.step, self.stop, self.lived, self.errors = step, threading.Event(), [], []
        self.opened = 0  # connections its first step opened

    def run(self):
        try:
            while not self.stop.is_set():
                self.step(self)
        except Exception as e:  # noqa: BLE001 - reported by the test
            self.errors.append(repr(e))


def trickle(port, prefix, start_bytes=b""):
    """An attack step: connections (8 at once) that send `start_bytes`, then `prefix` one
    byte a second; each records how long it lived once the server closed it."""
    def step(attack):
        sel = selectors.DefaultSelector()
        conns = []
        for _ in range(8):
            s = socket.create_connection(("127.0.0.1", port))
            s.sendall(start_bytes)
            s.setblocking(False)
            sel.register(s, selectors.EVENT_READ)
            conns.append([s, time.time(), 0])
        attack.opened = attack.opened or len(conns)
        open_ = {c[0]: c for c in conns}
        next_byte = time.time()
        while open_ and not attack.stop.is_set():
            for key, _ in sel.select(timeout=0.1):
                s = key.fileobj
                try:
                    data = s.recv(4096)
                except OSError:
                    data = b""
                if not data:  # closed by the server (a reply first would be read as data)
                    attack.lived.append(time.time() - open_[s][1])
                    sel.unregister(s)
                    s.close()
                    del open_[s]
            if time.time() >= next_byte:
                next_byte += 1.0
                for s, c in list(open_.items()):
                    if c[2] >= len(prefix):
                        attack.errors.append("the whole trickled request was sent: not cut off")
                        attack.stop.set()
                        break
                    try:
                        s.send(prefix[c[2]:c[2] + 1])
                        c[2] += 1
                    except OSError:
                        pass  # closed: the read above records it
        for s in open_:
            s.close()
        sel.close()
    return step


def silent_flood(ports, count):
    """An attack step: `count` connections to each port that never send; each records how
    long it lived once closed by the server."""
    def step(attack):
        sel = selectors.DefaultSelector()
        start = {}
        for port in ports:
            for _ in range(count):
                s = socket.socket()
                s.setblocking(False)
                s.connect_ex(("127.0.0.1", port))
                sel.register(s, selectors.EVENT_READ)
                start[s] = time.time()
        attack.opened = len(start)
        while start and not attack.stop.is_set():
            for key, _ in sel.select(timeout=0.1):
                s = key.fileobj
                try:
                    data = s.recv(16)
                except OSError:
                    data = b""
                if data:
                    attack.errors.append(f"a silent connection was sent {data!r}")
                attack.lived.append(time.time() - start.pop(s))
                sel.unregister(s)
                s.close()
        for s in start:
            s.close()
        sel.close()
        attack.stop.wait()  # one flood: none opened after the server has cut this one
    return step


class Limits(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # 2 x FLOOD connections held by this process and by sdfd (which inherits the limit).
        print(f"\n  flood: {FLOOD} connections a port (descriptor limit {FD_SOFT}, hard "
              f"{FD_HARD})", file=sys.stderr)
        cls.server = Server("--timeout", str(TIMEOUT), "--max-connections", str(FLOOD + 64),
                            "--max-per-ip", str(FLOOD + 64))
        cls.prober = Prober(cls.server)
        cls.prober.medians(1)  # warm up both paths

    @classmethod
    def tearDownClass(cls):
        cls.prober.close()
        cls.server.stop()

    def under_attack(self, step, seconds=6, settled=None):
        """Idle medians, then medians while `step` attacks; checks the latency bounds and
        returns the finished attack, stopped once `settled(attack)` (if given) holds or 10 s
        after the measurement."""
        idle_http, idle_bin, n_idle = self.prober.medians(3)
        pid = self.server.proc.pid
        fds = open_fds(pid)
        attack = Attack(step)
        attack.start()
        # Measured once sdfd has accepted the attack's connections (a descriptor each).
        accepted = wait_until(lambda: attack.errors or (attack.opened and
                                                        open_fds(pid) >= fds + attack.opened), 30)
        self.assertEqual(attack.errors, [])
        self.assertTrue(accepted, f"sdfd did not accept the attack's {attack.opened} connections")
        http_s, bin_s, n = self.prober.medians(seconds)
        if settled:
            wait_until(lambda: settled(attack), 10)
        attack.stop.set()
        attack.join(30)
        print(f"\n  {self.id().rsplit('.', 1)[1]}: median us idle / attacked: HTTP "
              f"{idle_http * 1e6:.0f} / {http_s * 1e6:.0f} ({http_s / idle_http:.2f}x), binary "
              f"{idle_bin * 1e6:.0f} / {bin_s * 1e6:.0f} ({bin_s / idle_bin:.2f}x); "
              f"{n_idle} / {n} samples; connections lived {min(attack.lived, default=0):.2f}.."
              f"{max(attack.lived, default=0):.2f} s ({len(attack.lived)})", file=sys.stderr)
        self.assertEqual(attack.errors, [])
        self.assertLess(http_s, LATENCY_FACTOR * idle_http, "HTTP latency under attack")
        self.assertLess(bin_s, LATENCY_FACTOR * idle_bin, "binary latency under attack")
        return attack

    def assert_cut_in_time(self, attack, least):
        self.assertGreaterEqual(len(attack.lived), least, "too few connections were cut off")
        self.assertLessEqual(max(attack.lived), TIMEOUT + SLACK, "a connection outlived --timeout")
        self.assertGreaterEqual(min(attack.lived), TIMEOUT - 0.2, "cut off before --timeout")

    def test_http_slowloris_headers(self):
        attack = self.under_attack(trickle(
            self.server.ports["http"], b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Pad: " + b"a" * 64))
        self.assert_cut_in_time(attack, 16)

    def test_http_slowloris_body(self):
        head = (b"POST /v1/meshes/demo/query HTTP/1.1\r\nHost: x\r\n"
                b"Content-Type: application/json\r\nContent-Length: 64\r\n\r\n")
        attack = self.under_attack(trickle(self.server.ports["http"], b" " * 64, head))
        self.assert_cut_in_time(attack, 16)

    def test_binary_slowloris(self):
        attack = self.under_attack(trickle(self.server.bin_port, query_frame(1) * 4))
        self.assert_cut_in_time(attack, 16)

    def test_binary_slowloris_after_a_frame(self):
        """A connection that spoke once is kept while idle, but not while trickling."""
        whole = query_frame(1)
        attack = self.under_attack(trickle(self.server.bin_port, query_frame(2) * 4, whole))
        self.assertGreaterEqual(len(attack.lived), 16)
        # The first frame's reply is read as data, so the cut-off is seen at the next step.
        self.assertLessEqual(max(attack.lived), TIMEOUT + SLACK)

    def test_silent_connection_flood(self):
        pid = self.server.proc.pid
        before = open_fds(pid)
        # Measured while all of them are open; then the attack lasts until the server has
        # cut them all (the binary loop looks at their clocks once a second).
        attack = self.under_attack(silent_flood(
            [self.server.ports["http"], self.server.bin_port], FLOOD), seconds=TIMEOUT - 0.5,
            settled=lambda a: len(a.lived) >= 2 * FLOOD)
        self.assertEqual(attack.opened, 2 * FLOOD)
        self.assert_cut_in_time(attack, 2 * FLOOD)
        self.assertTrue(wait_until(lambda: open_fds(pid) <= before, 10),
                        f"sdfd holds {open_fds(pid)} descriptors, {before} before the flood")


class NonReader(unittest.TestCase):
    """A binary client that sends queries and never reads. With a longer --timeout, so that
    the server's backpressure (it stops reading) shows before the cut-off."""

    # In a sanitizer build the queries it reads take long enough to compute that 64 MiB of
    # replies pile up only after several seconds more.
    T = 30 if SANITIZED else 8

    def test_binary_client_that_never_reads(self):
        with Server("--timeout", str(self.T)) as s:
            prober = Prober(s)
            prober.medians(1)
            idle_http, idle_bin, _ = prober.medians(3)
            base_rss = rss_bytes(s.proc.pid)
            sock = socket.create_connection(("127.0.0.1", s.bin_port))
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.settimeout(0.2)
            frame = query_frame(1, n=1000, mode=3)  # 12 KB in, 20 KB of replies out
            sent, progress, cut, peak = 0, [], None, 0
            t0 = time.time()

            def sender():
                nonlocal sent, cut, peak
                while cut is None and time.time() - t0 < self.T + 10:
                    try:
                        sent += sock.send(frame)
                    except socket.timeout:
                        pass
                    except OSError:
                        cut = time.time() - t0
                    progress.append((time.time() - t0, sent))
                    peak = max(peak, rss_bytes(s.proc.pid))
            t = threading.Thread(target=sender, daemon=True)
            t.start()
            # Measure once the server has stopped reading it (no send went through for 1 s):
            # before that it computes the queries it reads, which is load, not an attack. It
            # stops for good only with 64 MiB of replies unsent (binary.c); a pause before
            # that many frames are in is the limit of 64 queries in flight waiting on their
            # computation (seconds long under ThreadSanitizer), which then reads on.
            full = 0.9 * (64 * 2**20 / 20000) * len(frame)
            plateau = None
            while plateau is None and time.time() - t0 < self.T and cut is None:
                time.sleep(0.2)
                recent = [b for when, b in progress[-2000:] if when >= time.time() - t0 - 1.0]
                if time.time() - t0 > 1.0 and recent and recent[0] == sent and sent >= full:
                    plateau = time.time() - t0
            held = sent
            http_s, bin_s, _ = prober.medians(3)
            t.join(30)
            sock.close()
            prober.close()
            print(f"\n  non-reader: sent {sent / 1e6:.1f} MB, stalled at {plateau} s, cut after "
                  f"{cut} s, sdfd RSS {base_rss / 1e6:.0f} -> peak {peak / 1e6:.0f} MB; median us "
                  f"idle / attacked: HTTP {idle_http * 1e6:.0f} / {http_s * 1e6:.0f}, binary "
                  f"{idle_bin * 1e6:.0f} / {bin_s * 1e6:.0f}", file=sys.stderr)
            self.assertIsNotNone(cut, "the non-reading client was never cut off")
            if plateau is None and SANITIZED:
                # Computed slowly, its replies stalled in the socket for --timeout before 64
                # MiB of them piled up: the cut came first, a --timeout after the start's
                # few seconds of sending.
                self.assertLessEqual(cut, 2 * self.T)
            else:
                self.assertIsNotNone(plateau,
                                     "the server kept reading the client that does not read")
                self.assertEqual(held, sent, "the server read more after it had stopped")
                self.assertLessEqual(cut, plateau + self.T + SLACK)
            # It buffered at most its 64 MiB of unsent replies (plus the frames in flight);
            # AddressSanitizer also keeps up to 256 MiB of freed memory in its quarantine, and
            # ThreadSanitizer's shadow memory is several times what the program touches.
            quarantine = 256 * 2**20 if "address" in os.environ.get("SDF_SANITIZE", "") else 0
            quarantine += 512 * 2**20 if "thread" in os.environ.get("SDF_SANITIZE", "") else 0
            self.assertLess(peak - base_rss, 160e6 + quarantine)
            if plateau is not None:  # else the probes waited behind its queries: load
                self.assertLess(http_s, LATENCY_FACTOR * idle_http, "HTTP latency under attack")
                self.assertLess(bin_s, LATENCY_FACTOR * idle_bin, "binary latency under attack")


if __name__ == "__main__":
    unittest.main(verbosity=2)
