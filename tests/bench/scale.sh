#!/bin/sh
# The scale check: refined_elephant.off (88,928 triangles) against the same surface
# subdivided twice (1,422,848 triangles, tests/bench/subdivide.py): index build time, index
# bytes per triangle (from the mesh report) and band throughput, and the ratio of the two
# throughputs. Prints a Markdown table. Needs a release build in build/ (or BUILD).
#
#   tests/bench/scale.sh            Environment: N (default 1000000), THREADS (default 2),
#                                   WORK (scratch dir for the big mesh, default /tmp/sdfd-scale),
#                                   MESH (an OFF file, default refined_elephant), TIMES (2)
set -eu
cd "$(dirname "$0")/../.."
n=${N:-1000000}
threads=${THREADS:-2}
work=${WORK:-/tmp/sdfd-scale}
src=${MESH:-tests/data/refined_elephant.off}
times=${TIMES:-2}
builddir=${BUILD:-build}
big=$work/$(basename "$src" .off)_x$((1 << (2 * times))).off
mkdir -p "$work"
[ -s "$big" ] || /usr/bin/python3 tests/bench/subdivide.py "$src" "$big" --times "$times" >&2

echo "| mesh | triangles | build s | index B/triangle | band Mq/s | band vs original |"
echo "| --- | ---: | ---: | ---: | ---: | ---: |"
base=""
for mesh in "$src" "$big"; do
    out=$("$builddir/tests/bench/sdf-bench" "$mesh" --workload band --n "$n" --threads "$threads")
    tris=$(echo "$out" | sed -n 's/.* triangles: \([0-9]*\) .*/\1/p')
    bpt=$(echo "$out" | sed -n 's/.* (\([0-9.]*\) B\/triangle).*/\1/p')
    build=$(echo "$out" | sed -n 's/.* build: \([0-9.]*\) s.*/\1/p')
    mqs=$(echo "$out" | sed -n 's/throughput: \([0-9.]*\) Mq\/s/\1/p')
    base=${base:-$mqs}
    awk -v m="$(basename "$mesh")" -v t="$tris" -v b="$build" -v bpt="$bpt" -v q="$mqs" -v q0="$base" \
        'BEGIN { printf "| %s | %d | %.2f | %.1f | %.3f | %.2f |\n", m, t, b, bpt, q, q / q0 }'
done
