#!/usr/bin/python3
"""extract_bench.py - sdfd's surface extraction (sdf_volume_extract, through sdf-volume mesh)
side by side with its peers on the same grid of values, in one run: skimage.measure.
marching_cubes (Debian's python3-skimage) and OpenVDB's volumeToMesh (python3-openvdb's
convertToPolygons) on a FloatGrid holding the same dense values, and, for scale, OpenVDB's
convertToPolygons on its own narrow-band level set of the mesh (createLevelSetFromPolygons,
voxels the grid's smallest spacing, half width 3).

The grid: the mesh baked by sdf-volume at --resolution^3 nodes (zero order, float32). Each
surface is timed --repeat times (best kept; the peers' Python-side copies not timed), and
measured against the mesh: the Hausdorff distance over vertices (each surface's vertices to
the mesh, the mesh's vertices to the surface, through sdf-bench's exact distances), in cells
(the grid's largest spacing). Prints a Markdown table.

    tests/bench/extract_bench.py [--mesh tests/data/refined_elephant.off] [--resolution 512]
                                 [--repeat 3] [--build build]"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def run(cmd):
    out = subprocess.run([str(c) for c in cmd], check=True, stdout=subprocess.PIPE,
                         text=True).stdout
    return json.loads(out.strip().splitlines()[-1]) if out.strip().startswith("{") else out


def write_off(path, verts, tris):
    with open(path, "w") as f:
        f.write(f"OFF\n{len(verts)} {len(tris)} 0\n")
        np.savetxt(f, verts, fmt="%.9g")
        np.savetxt(f, np.hstack([np.full((len(tris), 1), 3), tris]), fmt="%d")


def distances(build, mesh, points, tmp):
    """Unsigned distances from points (float32 (N, 3)) to mesh, by sdf-bench."""
    pts, out = tmp / "points.npy", tmp / "dist.npy"
    np.save(pts, np.ascontiguousarray(points, np.float32))
    subprocess.run([str(build / "tests/bench/sdf-bench"), str(mesh), str(pts), "--mode",
                    "distance", "--repeat", "1", "--out", str(out)], check=True,
                   stdout=subprocess.DEVNULL)
    return np.abs(np.load(out))


def hausdorff(build, original, orig_verts, verts, tris, cell, tmp):
    surface = tmp / "surface.off"
    write_off(surface, verts, tris)
    a = distances(build, original, verts, tmp).max()
    b = distances(build, surface, orig_verts, tmp).max()
    return max(a, b) / cell


def best_of(repeat, fn):
    best, result = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def read_off(path):
    words = []
    with open(path) as f:
        for line in f:
            words.extend(line.split("#", 1)[0].split())
    nv, nf = int(words[1]), int(words[2])
    v = np.array(words[4:4 + 3 * nv], np.float64).reshape(nv, 3)
    f = np.array(words[4 + 3 * nv:4 + 3 * nv + 4 * nf], np.int64).reshape(nf, 4)[:, 1:]
    return v, f


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", default=str(ROOT / "tests/data/refined_elephant.off"))
    ap.add_argument("--resolution", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--build", type=Path, default=ROOT / "build")
    a = ap.parse_args()
    import pyopenvdb as vdb
    import skimage.measure
    with tempfile.TemporaryDirectory(prefix="extract-bench-") as d:
        tmp = Path(d)
        tool = a.build / "tests/bench/sdf-volume"
        meta = run([tool, "bake", a.mesh, tmp / "vol.npy", "--format", "npy", "--resolution",
                    a.resolution, "--threads", "2"])
        origin, spacing = np.array(meta["origin"]), np.array(meta["spacing"])
        cell = spacing.max()
        orig_verts, orig_tris = read_off(a.mesh)
        rows = []

        ours = run([tool, "mesh", tmp / "vol.npy", tmp / "ours.off", "--threads", "2",
                    "--repeat", a.repeat, "--origin", ",".join(map(repr, origin)),
                    "--spacing", ",".join(map(repr, spacing))])
        v, t = read_off(tmp / "ours.off")
        rows.append(("sdfd (sdf_volume_extract, 2 threads)", ours["seconds"], len(t),
                     hausdorff(a.build, a.mesh, orig_verts, v, t, cell, tmp)))
        print(f"sdfd: {ours['seconds']:.3f} s", file=sys.stderr)

        vol = np.load(tmp / "vol.npy")  # (K, M, N): z, y, x
        secs, (verts, faces, _, _) = best_of(min(a.repeat, 2), lambda: skimage.measure.
                                              marching_cubes(vol, 0.0, spacing=tuple(spacing[::-1])))
        verts = verts[:, ::-1] + origin
        rows.append(("skimage.measure.marching_cubes (1 thread)", secs, len(faces),
                     hausdorff(a.build, a.mesh, orig_verts, verts, faces, cell, tmp)))
        print(f"skimage: {secs:.3f} s", file=sys.stderr)

        matrix = np.diag([spacing[0], spacing[1], spacing[2], 1.0])
        matrix[3, :3] = origin
        grid = vdb.FloatGrid(background=float(cell) * 3)
        grid.copyFromArray(np.ascontiguousarray(vol.transpose(2, 1, 0)), tolerance=0)
        grid.transform = vdb.createLinearTransform(matrix.tolist())
        rows.append(vdb_row(vdb, "OpenVDB convertToPolygons, the dense values", grid, a, tmp,
                            orig_verts, cell))
        del grid
        ls = vdb.FloatGrid.createLevelSetFromPolygons(  # pyopenvdb reads float32 and int32
            orig_verts.astype(np.float32), triangles=orig_tris.astype(np.int32),
            transform=vdb.createLinearTransform(voxelSize=float(spacing.min())), halfWidth=3.0)
        rows.append(vdb_row(vdb, "OpenVDB convertToPolygons, its narrow-band level set", ls, a,
                            tmp, orig_verts, cell))
    print(f"{Path(a.mesh).name} at {a.resolution}^3 nodes; Hausdorff over vertices, in cells "
          f"of {cell:.5g}\n")
    print("| extraction | seconds | vs sdfd | triangles | Hausdorff (cells) |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, secs, tris, h in rows:
        print(f"| {name} | {secs:.3f} | {secs / rows[0][1]:.1f}x | {tris} | {h:.3f} |")


def vdb_row(vdb, name, grid, a, tmp, orig_verts, cell):
    secs, (points, tris, quads) = best_of(min(a.repeat, 2),
                                          lambda: grid.convertToPolygons(isovalue=0.0))
    quads = np.asarray(quads).reshape(-1, 4)
    faces = np.vstack([np.asarray(tris).reshape(-1, 3), quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    print(f"{name}: {secs:.3f} s", file=sys.stderr)
    return (name, secs, len(faces), hausdorff(a.build, a.mesh, orig_verts, np.asarray(points),
                                              faces, cell, tmp))


if __name__ == "__main__":
    main()
