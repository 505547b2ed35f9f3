"""A PostgreSQL server of a test's own, from Debian's packages, on a free loopback port.

The catalog's tests need a real server they can stop, restart and kill, so each starts its
own: `initdb` into a temporary directory, trust authentication on loopback only, the Unix
socket in that directory, `fsync` off (a test's data need not survive the machine, only the
server: a SIGKILLed postmaster loses nothing committed either way). PostgreSQL refuses to
run as root, so when the test runs as root the directory is given to `nobody` and every
server program runs as that user through `setpriv`; otherwise it runs as the caller.

    with PgServer() as pg:        # initdb and start
        connect(pg.uri)           # postgresql://postgres@127.0.0.1:PORT/postgres
        pg.stop(); pg.start()     # fast shutdown; the same data directory and port
        pg.kill()                 # SIGKILL the postmaster (start() recovers from it)
        pg.sql("SELECT 1")        # one statement through psql: its rows as text

PgServer(tls=(cert, key)) also serves TLS with that certificate (plain connections too).

Missing binaries raise PgServerError naming the package, so the test fails (never skips).
Python's standard library only."""
import atexit
import glob
import os
import pwd
import shutil
import signal
import socket
import subprocess
import tempfile
import time

BINDIR_DEFAULT = "/usr/lib/postgresql/15/bin"
PROGRAMS = ("initdb", "postgres", "psql")


class PgServerError(RuntimeError):
    pass


def find_bindir(candidates=None):
    """Debian's server binaries: the first of candidates holding initdb and postgres; by
    default $PG_BINDIR, /usr/lib/postgresql/15/bin, then the newest /usr/lib/postgresql/*/bin.
    Raises PgServerError, naming the package, when none does."""
    if candidates is None:
        candidates = [os.environ["PG_BINDIR"]] if os.environ.get("PG_BINDIR") else []
        candidates.append(BINDIR_DEFAULT)
        candidates += sorted(glob.glob("/usr/lib/postgresql/*/bin"), reverse=True)
    for d in candidates:
        if all(os.access(os.path.join(d, p), os.X_OK) for p in PROGRAMS):
            return d
    raise PgServerError("PostgreSQL server binaries (initdb, postgres) not found in %s: "
                        "install Debian's postgresql package (.ci/deps does)"
                        % ", ".join(candidates))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def children_of(pid):
    """The pids whose parent is pid (from /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open("/proc/%s/stat" % entry) as fh:
                    fields = fh.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(entry))
    return out


def alive(pid):
    """Is pid running (neither gone nor a zombie)?"""
    try:
        with open("/proc/%d/stat" % pid) as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


class PgServer:
    def __init__(self, port=None, log_statements=False, tls=None):
        self.bindir = find_bindir()
        self.port = port or free_port()
        self.dir = tempfile.mkdtemp(prefix="sdfd-pg-")
        self.data = os.path.join(self.dir, "data")
        self.log_path = os.path.join(self.dir, "postgres.log")
        self.proc = None
        self._prefix, self._owner = [], None
        if os.geteuid() == 0:
            user = pwd.getpwnam("nobody")
            self._owner = (user.pw_uid, user.pw_gid)
            os.chown(self.dir, *self._owner)
            self._prefix = ["setpriv", "--reuid=%d" % user.pw_uid, "--regid=%d" % user.pw_gid,
                            "--clear-groups", "--"]
        try:
            self._initdb(log_statements)
            if tls:
                self._install_tls(*tls)
        except BaseException:
            shutil.rmtree(self.dir, ignore_errors=True)
            raise
        atexit.register(self.cleanup)

    @property
    def uri(self):
        return self.uri_for("postgres")

    def uri_for(self, dbname):
        return "postgresql://postgres@127.0.0.1:%d/%s" % (self.port, dbname)

    def sql(self, query, dbname="postgres"):
        """Run one statement with psql; its rows as text, one a line, fields split by '|'."""
        done = subprocess.run([os.path.join(self.bindir, "psql"), "-X", "-A", "-t", "-q",
                               "-v", "ON_ERROR_STOP=1", "-c", query, self.uri_for(dbname)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd="/")
        if done.returncode != 0:
            raise PgServerError("psql %r failed: %s" % (query, done.stderr.decode(errors="replace")))
        return done.stdout.decode()

    def _program(self, name):
        return self._prefix + [os.path.join(self.bindir, name)]

    def _initdb(self, log_statements):
        cmd = self._program("initdb") + ["-D", self.data, "-U", "postgres", "-A", "trust",
                                         "-E", "UTF8", "--locale=C", "--no-sync"]
        done = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, cwd="/")
        if done.returncode != 0:
            raise PgServerError("initdb failed (%d):\n%s" %
                                (done.returncode, done.stdout.decode(errors="replace")))
        conf = ["listen_addresses = '127.0.0.1'", "port = %d" % self.port,
                "unix_socket_directories = '%s'" % self.dir, "fsync = off",
                "max_connections = 100", "shared_buffers = 32MB", "log_min_messages = warning",
                "log_statement = '%s'" % ("all" if log_statements else "none")]
        with open(os.path.join(self.data, "postgresql.conf"), "a") as fh:
            fh.write("\n".join(conf) + "\n")

    def _install_tls(self, cert, key):
        """Serve TLS (still accepting plain connections) with this certificate and key, copied
        into the data directory: PostgreSQL wants the key private to the server's user."""
        for src, name in ((cert, "server.crt"), (key, "server.key")):
            dst = os.path.join(self.data, name)
            shutil.copyfile(src, dst)
            os.chmod(dst, 0o600)
            if self._owner:
                os.chown(dst, *self._owner)
        with open(os.path.join(self.data, "postgresql.conf"), "a") as fh:
            fh.write("ssl = on\n")

    def start(self, timeout=30):
        """Start the postmaster and wait until it accepts connections."""
        if self.proc and self.proc.poll() is None:
            raise PgServerError("PostgreSQL is already running")
        log = open(self.log_path, "ab")
        try:
            self.proc = subprocess.Popen(self._program("postgres") + ["-D", self.data],
                                         stdout=log, stderr=subprocess.STDOUT, cwd="/")
        finally:
            log.close()
        deadline = time.monotonic() + timeout
        while not self._ready():
            if self.proc.poll() is not None:
                raise PgServerError("PostgreSQL exited (%d) at start:\n%s" %
                                    (self.proc.returncode, self.log_tail()))
            if time.monotonic() > deadline:
                self.kill()
                raise PgServerError("PostgreSQL not ready within %ds:\n%s" %
                                    (timeout, self.log_tail()))
            time.sleep(0.05)

    def _ready(self):
        """postmaster.pid names our process and says "ready" (what pg_ctl -w waits for)."""
        try:
            with open(os.path.join(self.data, "postmaster.pid")) as fh:
                lines = fh.read().splitlines()
        except OSError:
            return False
        return len(lines) >= 8 and lines[0] == str(self.proc.pid) and lines[7].strip() == "ready"

    def stop(self, timeout=30):
        """Fast shutdown (SIGINT): sessions are ended, then the postmaster exits."""
        if not self.proc or self.proc.poll() is not None:
            return
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()

    def kill(self):
        """SIGKILL the postmaster, as a crash would; its backends notice and exit, and start()
        waits for them (a new postmaster refuses to start while they hold shared memory)."""
        if not self.proc or self.proc.poll() is not None:
            return
        backends = children_of(self.proc.pid)
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait()
        deadline = time.monotonic() + 10
        while any(alive(p) for p in backends):
            if time.monotonic() > deadline:
                for p in backends:
                    try:
                        os.kill(p, signal.SIGKILL)
                    except OSError:
                        pass
            time.sleep(0.02)

    def restart(self):
        self.stop()
        self.start()

    def log_tail(self, n=40):
        try:
            with open(self.log_path, errors="replace") as fh:
                return "".join(fh.readlines()[-n:])
        except OSError:
            return "(no log)"

    def cleanup(self):
        """Stop (killing if it will not stop) and delete the directory."""
        try:
            self.stop(timeout=10)
        finally:
            self.kill()
            shutil.rmtree(self.dir, ignore_errors=True)

    def __enter__(self):
        try:
            self.start()
        except BaseException:
            self.cleanup()
            raise
        return self

    def __exit__(self, *exc):
        self.cleanup()
