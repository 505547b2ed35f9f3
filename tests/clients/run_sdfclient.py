"""Run test_sdfclient (libsdfclient's C test) against two real sdfd: one plain, one started
with --token s3cret --auth-queries. Started here with tests/server/harness.py, so the C test
need not parse sdfd's log for the ports; its exit code is this script's."""
import os
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "server"))
from harness import Server  # noqa: E402

with Server() as plain, Server("--token", "s3cret", "--auth-queries") as auth:
    env = dict(os.environ, SDFC_TEST_BIN=f"127.0.0.1:{plain.bin_port}",
               SDFC_TEST_AUTH_BIN=f"127.0.0.1:{auth.bin_port}")
    code = subprocess.run([os.environ["TEST_SDFCLIENT"]], env=env, timeout=240).returncode
sys.exit(code)
