"""Run test_catalog (the C test of server/state/catalog.c) against a PostgreSQL of its own.

Starts PostgreSQL with pgserver.py and runs the program given as the first argument with
the server's address in the environment (SDFD_TEST_PG_BASE, SDFD_TEST_PG_PORT) and two pipe
descriptors (SDFD_TEST_PGCTL="W,R") on which it asks for "stop", "start", "restart" or "kill"
and reads "ok" (or "error: ...") once done. Exits with the program's status; fails, never
skips, when PostgreSQL cannot be found or started (pgserver.PgServerError says why). On
failure the tail of PostgreSQL's log is printed."""
import os
import subprocess
import sys

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
    try:
        pg = pgserver.PgServer()
        pg.start()
    except pgserver.PgServerError as e:
        sys.exit("FAIL: %s" % e)
    to_parent_r, to_parent_w = os.pipe()
    to_child_r, to_child_w = os.pipe()
    env = dict(os.environ, SDFD_TEST_PG_BASE="postgresql://postgres@127.0.0.1:%d" % pg.port,
               SDFD_TEST_PG_PORT=str(pg.port),
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
    sys.exit(code)


if __name__ == "__main__":
    main()
