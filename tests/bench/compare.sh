#!/bin/sh
# Side-by-side throughput of sdf-bench and Open3D's RaycastingScene (via the peer script
# ../shared/tools/peer_bench.py) on identical points, in one run. Prints a Markdown table of
# both throughputs and their ratio. Needs python3-open3d (apt) and a release build in build/.
#
#   tests/bench/compare.sh [MESH...]        (default: fandisk and refined_elephant)
# Environment: WORKLOADS (default "box band"), N (default 1000000), THREADS (default 2),
#              MODE (default signed), SIGN (default auto).
set -eu
cd "$(dirname "$0")/../.."
peer=../shared/tools/peer_bench.py
bench=build/tests/bench/sdf-bench
[ "$#" -gt 0 ] || set -- ../shared/meshes/fandisk.off ../shared/meshes/refined_elephant.off
workloads=${WORKLOADS:-box band}
n=${N:-1000000}
threads=${THREADS:-2}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "| mesh | workload | points | Open3D Mq/s | sdfd Mq/s | ratio |"
echo "| --- | --- | ---: | ---: | ---: | ---: |"
for mesh in "$@"; do
    for w in $workloads; do
        o3d=$(/usr/bin/python3 "$peer" "$mesh" --workload "$w" --n "$n" --points-out "$tmp/p.npy" |
            awk '/^open3d:/ {print $2}')
        ours=$(OMP_NUM_THREADS=$threads "$bench" "$mesh" "$tmp/p.npy" --threads "$threads" \
            --mode "${MODE:-signed}" --sign "${SIGN:-auto}" | awk '/^throughput:/ {print $2}')
        ratio=$(awk -v a="$ours" -v b="$o3d" 'BEGIN {printf "%.2f", a / b}')
        echo "| $(basename "$mesh") | $w | $n | $o3d | $ours | $ratio |"
    done
done
