#!/bin/sh
# Volume bakes beside their peer, in one run (docs/performance.md, "Volumes"):
#  - sdfd's 128^3 zero-order and first-order bakes (tests/bench/bake-bench, all CPUs), their
#    time ratio (target: first order <= 4x zero order);
#  - OpenVDB's createLevelSetFromPolygons (Debian python3-openvdb, tests/bench/vdb_bake.py)
#    with voxels as large as our largest node spacing and a half width that covers the whole
#    box (the largest |distance| in it, in voxels, plus one): our nodes per second over its
#    active voxels per second (target: >= 5x).
# Each bake, ours and OpenVDB's, runs REPEAT times (default 3) and keeps its fastest: this
# machine's timings wander by 10-20 % from run to run. Prints a Markdown table, a row a mesh.
# usage: [REPEAT=N] tests/bench/bake-compare.sh [BUILD_DIR (build)] [DIM (128)] [MESH ...]
set -eu
cd "$(dirname "$0")/../.."
build=${1:-build}
dim=${2:-128}
repeat=${REPEAT:-3}
if [ "$#" -ge 2 ]; then shift 2; else shift "$#"; fi # dash exits on a failed shift
meshes=${*:-"tests/data/fandisk.off tests/data/refined_elephant.off"}
[ -f "$build/build.ninja" ] || { echo "no build in $build: meson setup first" >&2; exit 1; }
/usr/bin/python3 -c "import pyopenvdb" 2>/dev/null || {
    echo "needs Debian's python3-openvdb: apt-get install python3-openvdb" >&2
    exit 1
}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "| mesh | nodes | zero order s | M nodes/s | first order s | first / zero |" \
    "OpenVDB s | active voxels | M voxels/s | ours / OpenVDB |"
echo "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
for mesh in $meshes; do
    name=$(basename "$mesh" .off)
    "$build/tests/bench/bake-bench" "$mesh" "$dim" 0 "repeat=$repeat" > "$tmp/ours.json"
    "$build/tests/bench/sdf-volume" bake "$mesh" "$tmp/v.npy" --format npy --resolution "$dim" \
        > "$tmp/meta.json"
    set -- $(/usr/bin/python3 - "$tmp" <<'PY'
import json, math, sys
import numpy as np
tmp = sys.argv[1]
meta = json.load(open(tmp + "/meta.json"))
voxel = max(meta["spacing"])
half = math.ceil(float(np.abs(np.load(tmp + "/v.npy")).max()) / voxel) + 1
print(voxel, half)
PY
)
    /usr/bin/python3 tests/bench/vdb_bake.py "$mesh" "$1" "$2" "$repeat" > "$tmp/vdb.json"
    /usr/bin/python3 - "$tmp" "$name" "$dim" <<'PY'
import json, sys
tmp, name, dim = sys.argv[1], sys.argv[2], int(sys.argv[3])
ours = [json.loads(l) for l in open(tmp + "/ours.json")]
vdb = json.load(open(tmp + "/vdb.json"))
zero, first = ours[0], ours[1]
print(f"| {name}.off | {dim}^3 | {zero['seconds']:.3f} | {zero['nodes_per_second']/1e6:.2f} | "
      f"{first['seconds']:.3f} | {first['seconds']/zero['seconds']:.2f} | {vdb['seconds']:.3f} | "
      f"{vdb['active_voxels']} | {vdb['voxels_per_second']/1e6:.2f} | "
      f"{zero['nodes_per_second']/vdb['voxels_per_second']:.2f} |")
PY
done
