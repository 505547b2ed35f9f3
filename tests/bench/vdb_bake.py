#!/usr/bin/python3
"""OpenVDB's dense-enough level set as the peer of sdfd's zero-order bake (tests/bench/
bake-compare.sh): createLevelSetFromPolygons on an OFF mesh with cubic voxels of the given
size and a half width (in voxels) wide enough to cover the whole bake box. Prints one JSON
line: seconds, active voxels, active voxels per second. Needs Debian's python3-openvdb.

usage: vdb_bake.py MESH.off VOXEL_SIZE HALF_WIDTH_VOXELS [REPEAT]"""
import json
import sys
import time

import numpy as np
import pyopenvdb as vdb


def read_off(path):
    words = []
    with open(path) as f:
        for line in f:
            words.extend(line.split("#", 1)[0].split())
    if not words[0].endswith("OFF"):
        raise ValueError("not an OFF file")
    nv, nf = int(words[1]), int(words[2])
    at = 4
    v = np.array(words[at:at + 3 * nv], np.float64).reshape(nv, 3)
    at += 3 * nv
    tris = []
    for _ in range(nf):
        k = int(words[at])
        idx = [int(x) for x in words[at + 1:at + 1 + k]]
        tris.extend([idx[0], idx[i], idx[i + 1]] for i in range(1, k - 1))
        at += 1 + k
    return v.astype(np.float32), np.array(tris, np.int32)


def main():
    path, voxel, half = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    repeat = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    points, triangles = read_off(path)
    xform = vdb.createLinearTransform(voxelSize=voxel)
    best = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        grid = vdb.FloatGrid.createLevelSetFromPolygons(points, triangles=triangles,
                                                        transform=xform, halfWidth=half)
        seconds = time.perf_counter() - t0
        best = seconds if best is None else min(best, seconds)
    active = grid.activeVoxelCount()
    print(json.dumps({"peer": "openvdb", "seconds": round(best, 4), "active_voxels": active,
                      "voxels_per_second": round(active / best)}))


if __name__ == "__main__":
    main()
