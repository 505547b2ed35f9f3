#!/bin/sh
# The server's and its clients' throughput next to the in-process library's on the same
# points, in one run: starts sdfd on free ports with MESH and prints a Markdown table with each
# throughput as a ratio of an in-process one (sdf-bench, 2 threads, band workload).
#
# One request of all N points (the "1 x N" rows): sdfd-bench (binary, HTTP octet-stream, HTTP
# JSON; request bodies encoded before timing, replies received but not parsed: the server's
# cost plus transport), then each client, timed from the points in the program's memory to
# its decoded answer: the C client (libsdfclient, sdfc-bench), the JS client
# (clients/js/bench/client-bench.js: BinaryClient, and Client over fetch with octet-stream and
# JSON bodies) and the Python client (client_bench.py: BinaryClient, Client with octet and
# JSON). All read the points the first sdf-bench run wrote (--points-out), and the last column
# says whether a client's distances are the in-process ones bit for bit. Each of these rows
# takes R rounds, each an in-process run (sdf-bench on the same points) then the row's program
# (a warm-up request, then timed ones), each timing 2 calls; the row shows the best of all
# its timed calls and the in-process best of its rounds (the "in-process" column), the ratio's
# base. Interleaved so, the two sides of a ratio see the same moments of a machine shared with
# other work. "client CPU ms" is the client process's CPU time (user + system) per timed
# request, which that other work inflates far less than the wall time: what the client itself
# costs.
#
# 64 concurrent clients x 1,000 points over binary and octet-stream (sdfd-bench): their
# requests coalesce into batches of up to 64,000 points, so the in-process library on 64,000
# points is shown too, and a column compares the 64-client rows with it (what the server adds
# to a batch that size); the next compares them with the library called in-process the way
# those clients call the server, 1,000 points at a time (best of 200 calls on one request's
# points). These rows' ratios are against the first in-process run.
#
# Environment: N points (default 1000000), R rounds per 1 x N row (default 3), NODE (node).
# Needs a release build in build/ (or BUILD), node and /usr/bin/python3 with numpy.
#
#   tests/bench/server-compare.sh [MESH...]     (default: fandisk, refined_elephant)
set -eu
cd "$(dirname "$0")/../.."
[ "$#" -gt 0 ] || set -- tests/data/fandisk.off tests/data/refined_elephant.off
n=${N:-1000000}
r=${R:-3}
node=${NODE:-node}
build=${BUILD:-build}
tmp=$(mktemp -d)
log=$tmp/log
pid=
trap 'if [ -n "$pid" ]; then kill "$pid" 2>/dev/null; fi; rm -rf "$tmp"' EXIT

mqs() { awk '/^throughput:/ {print $2}'; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.2f", a / b}'; }

echo "| mesh | path | clients x points | Mq/s | in-process Mq/s | vs in-process |" \
    "latency p50 / p99 ms | vs in-process 64,000 | vs in-process 1,000 | client CPU ms |" \
    "same bits |"
echo "| --- | --- | --- | ---: | ---: | ---: | --- | ---: | ---: | ---: | --- |"
for mesh in "$@"; do
    "$build"/server/sdfd --http 127.0.0.1:0 --bin 127.0.0.1:0 --mesh "m=$mesh" 2>"$log" &
    pid=$!
    until grep -q '"event":"ready"' "$log"; do sleep 0.1; done
    http=$(grep '"proto":"http"' "$log" | sed 's/.*"port":\([0-9]*\).*/\1/')
    bin=$(grep '"proto":"binary"' "$log" | sed 's/.*"port":\([0-9]*\).*/\1/')
    name=$(basename "$mesh")
    base=$("$build"/tests/bench/sdf-bench "$mesh" --workload band --n "$n" --threads 2 \
        --repeat "$r" --points-out "$tmp/points.npy" --out "$tmp/expect.npy" | mqs)
    tail -c $((4 * n)) "$tmp/expect.npy" >"$tmp/expect.f32"
    echo "| $name | in-process sdf-bench | 1 x $n | $base | $base | 1.00 | | | | | |"
    small=$("$build"/tests/bench/sdf-bench "$mesh" --workload band --n 64000 --threads 2 \
        --repeat 20 | mqs)
    echo "| $name | in-process sdf-bench | 1 x 64000 | $small | $base |" \
        "$(ratio "$small" "$base") | | 1.00 | | | |"
    request=$("$build"/tests/bench/sdf-bench "$mesh" --workload band --n 1000 --threads 2 \
        --repeat 200 | mqs)
    echo "| $name | in-process sdf-bench | 1 x 1000 | $request | $base |" \
        "$(ratio "$request" "$base") | | | 1.00 | | |"

    # One request of all N points, each row in rounds with in-process runs.
    max() { awk -v a="$1" -v b="$2" 'BEGIN {print (a > b ? a : b)}'; }
    one() { # label check|- command... (the command takes --repeat)
        label=$1 check=$2
        shift 2
        pair=0 v=0 cpus=
        for _ in $(seq "$r"); do
            pair=$(max "$pair" "$("$build"/tests/bench/sdf-bench "$mesh" "$tmp/points.npy" \
                --threads 2 --repeat 2 | mqs)")
            rm -f "$tmp/got.f32"
            out=$("$@" --repeat 2)
            v=$(max "$v" "$(echo "$out" | mqs)")
            cpus="$cpus $(echo "$out" | awk '/^client cpu ms:/ {print $4}')"
        done
        cpu=$(echo "$cpus" | awk 'NF {s = 0; for (i = 1; i <= NF; i++) s += $i;
            printf "%.1f", s / NF}')
        same=
        if [ "$check" = check ]; then
            same=$(cmp -s "$tmp/expect.f32" "$tmp/got.f32" && echo yes || echo NO)
        fi
        echo "| $name | $label | 1 x $n | $v | $pair | $(ratio "$v" "$pair") | | | | $cpu |" \
            "$same |"
    }
    for form in binary octet json; do
        one "sdfd-bench $form" - "$build"/tests/bench/sdfd-bench "$mesh" "$tmp/points.npy" \
            --name m --http "127.0.0.1:$http" --bin "127.0.0.1:$bin" --form "$form"
    done
    one "C client binary" check "$build"/tests/bench/sdfc-bench "$tmp/points.npy" \
        --bin "127.0.0.1:$bin" --name m --out "$tmp/got.f32"
    for form in binary octet json; do
        one "JS client $form" check "$node" clients/js/bench/client-bench.js \
            "$tmp/points.npy" --form "$form" --bin "127.0.0.1:$bin" \
            --http "http://127.0.0.1:$http" --name m --out "$tmp/got.f32"
    done
    for form in binary octet json; do
        one "Python client $form" check /usr/bin/python3 tests/bench/client_bench.py \
            "$tmp/points.npy" --form "$form" --bin "127.0.0.1:$bin" \
            --http "http://127.0.0.1:$http" --name m --out "$tmp/got.f32"
    done

    # 64 clients of 1,000 points.
    for form in binary octet; do
        out=$("$build"/tests/bench/sdfd-bench "$mesh" --name m --http "127.0.0.1:$http" \
            --bin "127.0.0.1:$bin" --n "$n" --form "$form" --clients 64 --per-request 1000)
        v=$(echo "$out" | mqs)
        lat=$(echo "$out" | awk '/^latency/ {print $4 " / " $6}')
        echo "| $name | sdfd-bench $form | 64 x 1000 | $v | $base | $(ratio "$v" "$base") |" \
            "$lat | $(ratio "$v" "$small") | $(ratio "$v" "$request") | | |"
    done
    kill "$pid"
    wait "$pid" 2>/dev/null || true
    pid=
done
