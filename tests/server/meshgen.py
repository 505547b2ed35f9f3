"""meshgen.py - small meshes made on the spot for the tests and benchmarks that write many
versions of a name: each one's triangle count tells which it is. Standard library only."""
import math


def bipyramid(k):
    """A closed mesh of 2k triangles (k >= 3) as OFF text: a ring of k vertices on the unit
    circle and two apexes at z = +-1."""
    ring = [(math.cos(2 * math.pi * i / k), math.sin(2 * math.pi * i / k), 0.0)
            for i in range(k)]
    v = ring + [(0.0, 0.0, 1.0), (0.0, 0.0, -1.0)]
    f = [(i, (i + 1) % k, k) for i in range(k)] + [((i + 1) % k, i, k + 1) for i in range(k)]
    lines = ["OFF", f"{len(v)} {len(f)} 0"] + ["%.6f %.6f %.6f" % p for p in v]
    return ("\n".join(lines + ["3 %d %d %d" % t for t in f]) + "\n").encode()
