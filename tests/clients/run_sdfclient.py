"""Run test_sdfclient (libsdfclient's C test) against four real sdfd: one plain, one started
with --token s3cret --auth-queries, one with --bin-tls and a certificate for 127.0.0.1 and
localhost, and one with --bin-tls and a certificate that names another host, both signed by
a CA made here with certtool (as tests/server/test_tls.py does), with a second CA that
signed neither. Started here with tests/server/harness.py, so the C test need not parse
sdfd's log for the ports; its exit code is this script's."""
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "server"))
from harness import Server  # noqa: E402
from test_tls import certtool, make_ca, make_server_cert  # noqa: E402


def make_elsewhere_cert(d, ca):
    """A server certificate signed by ca for the name elsewhere.invalid only."""
    key, cert, tmpl = (os.path.join(d, f"elsewhere.{e}") for e in ("key", "pem", "tmpl"))
    with open(tmpl, "w") as f:
        f.write('cn = "elsewhere.invalid"\ndns_name = "elsewhere.invalid"\ntls_www_server\n'
                "signing_key\nencryption_key\nexpiration_days = 2\n")
    certtool("--generate-privkey", "--key-type=ecdsa", "--outfile", key)
    certtool("--generate-certificate", "--load-privkey", key, "--load-ca-certificate", ca[0],
             "--load-ca-privkey", ca[1], "--template", tmpl, "--outfile", cert)
    return cert, key


def tls_args(pair):
    return ("--tls-cert", pair[0], "--tls-key", pair[1], "--bin-tls")


certs = tempfile.mkdtemp(prefix="sdfclient-tls-")
try:
    ca = make_ca(certs, "ca")
    other_ca = make_ca(certs, "other-ca")
    served = make_server_cert(certs, "server", ca, 0x3003)
    elsewhere = make_elsewhere_cert(certs, ca)
    with Server() as plain, Server("--token", "s3cret", "--auth-queries") as auth, \
            Server(*tls_args(served)) as tls, Server(*tls_args(elsewhere)) as other:
        env = dict(os.environ, SDFC_TEST_BIN=f"127.0.0.1:{plain.bin_port}",
                   SDFC_TEST_AUTH_BIN=f"127.0.0.1:{auth.bin_port}",
                   SDFC_TEST_TLS_BIN=f"127.0.0.1:{tls.bin_port}",
                   SDFC_TEST_ELSEWHERE_BIN=f"127.0.0.1:{other.bin_port}",
                   SDFC_TEST_CA=ca[0], SDFC_TEST_OTHER_CA=other_ca[0])
        code = subprocess.run([os.environ["TEST_SDFCLIENT"]], env=env, timeout=240).returncode
finally:
    shutil.rmtree(certs, ignore_errors=True)
sys.exit(code)
