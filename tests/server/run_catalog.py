"""Run test_catalog (the C test of server/state/catalog.c) against a PostgreSQL of its own.

Starts PostgreSQL with pgserver.py, serving TLS with a certificate for 127.0.0.1 that certtool
(gnutls-bin) makes here, and runs the program given as the first argument with the server's
address in the environment (SDFD_TEST_PG_BASE, SDFD_TEST_PG_PORT), the CA that signed the
certificate and another one (SDFD_TEST_PG_CA, SDFD_TEST_PG_OTHER_CA), and two pipe
descriptors (SDFD_TEST_PGCTL="W,R") on which it asks for "stop", "start", "restart" or "kill"
and reads "ok" (or "error: ...") once done. Exits with the program's status; fails, never
skips, when PostgreSQL cannot be found or started (pgserver.PgServerError says why). On
failure the tail of PostgreSQL's log is printed."""
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import pgserver  # noqa: E402


def serve_commands(pg, commands, replies):
    """Answer the test's requests until it closes its end."""
    actions = {"stop": pg.stop, "start": pg.start, "restart": pg.restart, "kill": pg.kill}
    for line in commands:
        action = actions.get(line.strip())
        try:
            if not action:
                raise ValueError("unknown command %r" % line.strip())
            action()
            replies.write("ok\n")
        except Exception as e:  # the test reports it and goes on
            replies.write("error: %s\n" % str(e).replace("\n", " "))
        replies.flush()


def certtool(*args):
    subprocess.run(["certtool", *args], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)


def make_ca(d, name):
    """A self-signed CA in d: (certificate path, key path)."""
    key, cert, tmpl = (os.path.join(d, "%s.%s" % (name, e)) for e in ("key", "pem", "tmpl"))
    with open(tmpl, "w") as f:
        f.write('cn = "%s"\nca\ncert_signing_key\nexpiration_days = 2\n' % name)
    certtool("--generate-privkey", "--key-type=ecdsa", "--outfile", key)
    certtool("--generate-self-signed", "--load-privkey", key, "--template", tmpl,
             "--outfile", cert)
    return cert, key


def make_server_cert(d, ca):
    """A certificate for 127.0.0.1 and localhost signed by ca: (certificate, key)."""
    key, cert, tmpl = (os.path.join(d, "server.%s" % e) for e in ("key", "pem", "tmpl"))
    with open(tmpl, "w") as f:
        f.write('cn = "localhost"\ndns_name = "localhost"\nip_address = "127.0.0.1"\n'
                "tls_www_server\nsigning_key\nencryption_key\nexpiration_days = 2\n")
    certtool("--generate-privkey", "--key-type=ecdsa", "--outfile", key)
    certtool("--generate-certificate", "--load-privkey", key, "--load-ca-certificate", ca[0],
             "--load-ca-privkey", ca[1], "--template", tmpl, "--outfile", cert)
    return cert, key


def check_missing_binaries_fail():
    """Without the binaries the test fails with a message naming the package."""
    try:
        pgserver.find_bindir(["/nonexistent/postgresql/bin"])
    except pgserver.PgServerError as e:
        if "postgresql package" not in str(e):
            sys.exit("FAIL: unclear message for missing binaries: %s" % e)
    else:
        sys.exit("FAIL: find_bindir accepted a directory without PostgreSQL")


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: run_catalog.py TEST_PROGRAM")
    check_missing_binaries_fail()
    certs = tempfile.mkdtemp(prefix="sdfd-pg-certs-")
    try:
        ca, other = make_ca(certs, "ca"), make_ca(certs, "other")
        pg = pgserver.PgServer(tls=make_server_cert(certs, ca))
        pg.start()
    except (pgserver.PgServerError, subprocess.CalledProcessError, OSError) as e:
        shutil.rmtree(certs)
        sys.exit("FAIL: %s" % e)
    to_parent_r, to_parent_w = os.pipe()
    to_child_r, to_child_w = os.pipe()
    env = dict(os.environ, SDFD_TEST_PG_BASE="postgresql://postgres@127.0.0.1:%d" % pg.port,
               SDFD_TEST_PG_PORT=str(pg.port), SDFD_TEST_PG_CA=ca[0],
               SDFD_TEST_PG_OTHER_CA=other[0],
               SDFD_TEST_PGCTL="%d,%d" % (to_parent_w, to_child_r))
    try:
        proc = subprocess.Popen([sys.argv[1]], env=env, pass_fds=(to_parent_w, to_child_r))
        os.close(to_parent_w)
        os.close(to_child_r)
        with os.fdopen(to_parent_r) as commands, os.fdopen(to_child_w, "w") as replies:
            serve_commands(pg, commands, replies)
        code = proc.wait()
        if code != 0:
            print("--- PostgreSQL's log (tail) ---\n" + pg.log_tail(), file=sys.stderr)
    finally:
        pg.cleanup()
        shutil.rmtree(certs)
    sys.exit(code)


if __name__ == "__main__":
    main()
