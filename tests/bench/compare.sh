#!/bin/sh
# Side-by-side throughput of sdf-bench and Open3D's RaycastingScene (via the peer script
# tests/bench/peer_bench.py) on identical points, in one run. Prints a Markdown table of
# Open3D's throughput, sdfd's with packet traversal (the default), the same with one
# sdf_workspace kept across the timed calls (--workspace 1, as sdfd's batcher runs them), and
# with one query at a time (--traversal single), and the ratios. Needs python3-open3d (apt)
# and a release build in build/ (or BUILD, a build directory).
#
#   tests/bench/compare.sh [MESH...]        (default: fandisk and refined_elephant)
# Environment: WORKLOADS (default "box band"), N (default 1000000), THREADS (default 2),
#              MODE (default signed), SIGN (default auto).
set -eu
cd "$(dirname "$0")/../.."
peer=tests/bench/peer_bench.py
bench=${BUILD:-build}/tests/bench/sdf-bench
[ "$#" -gt 0 ] || set -- tests/data/fandisk.off tests/data/refined_elephant.off
workloads=${WORKLOADS:-box band}
n=${N:-1000000}
threads=${THREADS:-2}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "| mesh | workload | points | Open3D Mq/s | sdfd packets Mq/s | + workspace Mq/s | sdfd single Mq/s | packets / Open3D | + workspace / Open3D | packets / single |"
echo "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
for mesh in "$@"; do
    for w in $workloads; do
        o3d=$(/usr/bin/python3 "$peer" "$mesh" --workload "$w" --n "$n" --points-out "$tmp/p.npy" |
            awk '/^open3d:/ {print $2}')
        run() {
            "$bench" "$mesh" "$tmp/p.npy" --threads "$threads" --mode "${MODE:-signed}" \
                --sign "${SIGN:-auto}" --traversal "$1" --workspace "$2" |
                awk '/^throughput:/ {print $2}'
        }
        ours=$(run packets 0)
        kept=$(run packets 1)
        single=$(run single 0)
        ratio=$(awk -v a="$ours" -v b="$o3d" 'BEGIN {printf "%.2f", a / b}')
        kept_ratio=$(awk -v a="$kept" -v b="$o3d" 'BEGIN {printf "%.2f", a / b}')
        gain=$(awk -v a="$ours" -v b="$single" 'BEGIN {printf "%.2f", a / b}')
        echo "| $(basename "$mesh") | $w | $n | $o3d | $ours | $kept | $single | $ratio | $kept_ratio | $gain |"
    done
done
