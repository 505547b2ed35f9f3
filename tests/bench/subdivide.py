#!/usr/bin/python3
"""subdivide.py - 1-to-4 midpoint subdivision of an OFF triangle mesh, repeated.

Makes the packet issue's scale mesh: `subdivide.py refined_elephant.off OUT.off --times 2`
turns its 88,928 triangles into 1,422,848 on the same surface (each triangle is split at its
edge midpoints, shared between neighbours, so a closed manifold mesh stays closed and
manifold). Standard library + numpy only.

usage: subdivide.py IN.off OUT.off [--times N]
"""
import argparse
import sys

import numpy as np


def read_off(path):
    with open(path) as f:
        tokens = [t for line in f for t in line.split("#", 1)[0].split()]
    if not tokens or tokens[0] != "OFF":
        sys.exit(f"subdivide.py: {path}: not an OFF file")
    nv, nf = int(tokens[1]), int(tokens[2])
    at = 4
    v = np.array(tokens[at:at + 3 * nv], dtype=np.float64).reshape(nv, 3)
    at += 3 * nv
    faces = []
    for _ in range(nf):
        k = int(tokens[at])
        idx = [int(t) for t in tokens[at + 1:at + 1 + k]]
        at += 1 + k
        faces.extend([idx[0], idx[i], idx[i + 1]] for i in range(1, k - 1))  # fan
    return v, np.array(faces, dtype=np.int64)


def subdivide(v, t):
    """Split every triangle into four at its edge midpoints."""
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    key = np.sort(edges, axis=1)
    unique, inverse = np.unique(key, axis=0, return_inverse=True)
    mid = len(v) + inverse.reshape(3, len(t)).T  # midpoint vertex of edge k of each triangle
    v = np.concatenate([v, 0.5 * (v[unique[:, 0]] + v[unique[:, 1]])])
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    ab, bc, ca = mid[:, 0], mid[:, 1], mid[:, 2]
    t = np.concatenate([np.stack(s, axis=1) for s in
                        ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return v, t


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--times", type=int, default=2)
    args = ap.parse_args()
    v, t = read_off(args.input)
    for _ in range(args.times):
        v, t = subdivide(v, t)
    with open(args.output, "w") as f:
        f.write(f"OFF\n{len(v)} {len(t)} 0\n")
        np.savetxt(f, v, fmt="%.9g")
        np.savetxt(f, np.hstack([np.full((len(t), 1), 3), t]), fmt="%d")
    print(f"{args.output}: {len(v)} vertices, {len(t)} triangles")


if __name__ == "__main__":
    main()
