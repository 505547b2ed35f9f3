"""store_first_answer.py - time to the first answer for a mesh not in memory: PUT, pushed out
of memory by the PUT of a small mesh under --max-resident-bytes 1, then the first query, which
loads it from the --data-dir (read, hash check, parse, index build), and the next query for
comparison. A measurement for docs/performance.md, not a test.
usage (from the source root): SDFD=build/server/sdfd python3 tests/server/store_first_answer.py MESH...
"""
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "clients",
                                "python"))
import numpy as np  # noqa: E402
import sdfclient  # noqa: E402
from harness import DATA, Server  # noqa: E402


def main():
    d = tempfile.mkdtemp(prefix="sdfd-store-bench-")
    s = Server("--data-dir", d, "--max-resident-bytes", "1")
    c = sdfclient.Client(s.url)
    p = np.zeros((1, 3), np.float32)
    try:
        for i, path in enumerate(sys.argv[1:]):
            for rep in range(3):
                name = f"m{i}r{rep}"
                c.upload(name, path)
                c.upload("filler", os.path.join(DATA, "cube.ply"))  # evicts the other
                t = time.perf_counter()
                c.query(name, p, form="octet")
                first = time.perf_counter() - t
                t = time.perf_counter()
                c.query(name, p, form="octet")
                print(f"{os.path.basename(path)}: first answer {first:.3f} s, "
                      f"next {(time.perf_counter() - t) * 1000:.1f} ms")
                c.delete(name)
        for e in s.logs:
            if e.get("event") == "store_loaded":
                print(e["message"])
    finally:
        c.close()
        s.stop()
        shutil.rmtree(d)


if __name__ == "__main__":
    main()
