#!/bin/sh
# The server's throughput next to the in-process library's on the same points, in one run:
# starts sdfd on free ports with MESH, runs sdf-bench (in-process, 2 threads) and sdfd-bench
# (binary, HTTP octet-stream, HTTP JSON, each one request of N points; then 64 concurrent
# clients x 1,000 points over binary and octet-stream), and prints a Markdown table with each
# throughput as a ratio of the in-process one. The 64 clients' requests coalesce into batches
# of up to 64,000 points, so the in-process library on 64,000 points is shown too, and a
# column compares the 64-client rows with it (what the server adds to a batch that size);
# the next compares them with the library called in-process the way those clients call the
# server, 1,000 points at a time (best of 200 calls on one request's points). Both generate
# the band workload from the same seed, so the points are identical.
# The clients' rows time one request of all N points through each client, from the points in
# the program's memory to its decoded answer: the C client (libsdfclient, sdfc-bench), the JS
# client (clients/js/bench/client-bench.js: BinaryClient, and Client over fetch with
# octet-stream and JSON bodies) and the Python client (client_bench.py: BinaryClient, Client
# with octet and JSON). They read the points sdf-bench wrote (--points-out), and the last
# column says whether their distances are the in-process ones bit for bit.
# The 1 x N rows are each the best of R runs (environment R, default 3) after a warm-up.
# Needs a release build in build/, node and /usr/bin/python3 with numpy.
#
#   tests/bench/server-compare.sh [MESH...]     (default: fandisk, refined_elephant)
set -eu
cd "$(dirname "$0")/../.."
[ "$#" -gt 0 ] || set -- tests/data/fandisk.off tests/data/refined_elephant.off
n=${N:-1000000}
r=${R:-3}
node=${NODE:-node}
tmp=$(mktemp -d)
log=$tmp/log
pid=
trap 'if [ -n "$pid" ]; then kill "$pid" 2>/dev/null; fi; rm -rf "$tmp"' EXIT

mqs() { awk '/^throughput:/ {print $2}'; }

echo "| mesh | path | clients x points | Mq/s | vs in-process | latency p50 / p99 ms |" \
    "vs in-process 64,000 | vs in-process 1,000 | same bits |"
echo "| --- | --- | --- | ---: | ---: | --- | ---: | ---: | --- |"
for mesh in "$@"; do
    build/server/sdfd --http 127.0.0.1:0 --bin 127.0.0.1:0 --mesh "m=$mesh" 2>"$log" &
    pid=$!
    until grep -q '"event":"ready"' "$log"; do sleep 0.1; done
    http=$(grep '"proto":"http"' "$log" | sed 's/.*"port":\([0-9]*\).*/\1/')
    bin=$(grep '"proto":"binary"' "$log" | sed 's/.*"port":\([0-9]*\).*/\1/')
    base=$(build/tests/bench/sdf-bench "$mesh" --workload band --n "$n" --threads 2 \
        --repeat "$r" --points-out "$tmp/points.npy" --out "$tmp/expect.npy" | mqs)
    tail -c $((4 * n)) "$tmp/expect.npy" >"$tmp/expect.f32"
    name=$(basename "$mesh")
    echo "| $name | in-process sdf-bench | 1 x $n | $base | 1.00 | | | | |"
    small=$(build/tests/bench/sdf-bench "$mesh" --workload band --n 64000 --threads 2 \
        --repeat 20 | mqs)
    ratio() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.2f", a / b}'; }
    echo "| $name | in-process sdf-bench | 1 x 64000 | $small |" \
        "$(ratio "$small" "$base") | | 1.00 | | |"
    request=$(build/tests/bench/sdf-bench "$mesh" --workload band --n 1000 --threads 2 \
        --repeat 200 | mqs)
    echo "| $name | in-process sdf-bench | 1 x 1000 | $request |" \
        "$(ratio "$request" "$base") | | | 1.00 | |"
    run() { # form clients
        out=$(build/tests/bench/sdfd-bench "$mesh" --name m --http "127.0.0.1:$http" \
            --bin "127.0.0.1:$bin" --n "$n" --form "$1" --clients "$2" --per-request 1000 \
            --repeat "$r")
        v=$(echo "$out" | mqs)
        lat=$(echo "$out" | awk '/^latency/ {print $4 " / " $6}')
        shape=$([ "$2" = 1 ] && echo "1 x $n" || echo "$2 x 1000")
        vs_small=$([ "$2" = 1 ] && echo "" || ratio "$v" "$small")
        vs_request=$([ "$2" = 1 ] && echo "" || ratio "$v" "$request")
        echo "| $name | sdfd-bench $1 | $shape | $v | $(ratio "$v" "$base") | $lat | $vs_small | $vs_request | |"
    }
    client() { # label command...
        label=$1
        shift
        rm -f "$tmp/got.f32"
        v=$("$@" --out "$tmp/got.f32" | mqs)
        same=$(cmp -s "$tmp/expect.f32" "$tmp/got.f32" && echo yes || echo NO)
        echo "| $name | $label | 1 x $n | $v | $(ratio "$v" "$base") | | | | $same |"
    }
    clients() {
        client "C client binary" build/tests/bench/sdfc-bench "$tmp/points.npy" \
            --bin "127.0.0.1:$bin" --name m --repeat "$r"
        for form in binary octet json; do
            client "JS client $form" "$node" clients/js/bench/client-bench.js \
                "$tmp/points.npy" --form "$form" --bin "127.0.0.1:$bin" \
                --http "http://127.0.0.1:$http" --name m --repeat "$r"
        done
        for form in binary octet json; do
            client "Python client $form" /usr/bin/python3 tests/bench/client_bench.py \
                "$tmp/points.npy" --form "$form" --bin "127.0.0.1:$bin" \
                --http "http://127.0.0.1:$http" --name m --repeat "$r"
        done
    }
    run binary 1
    run octet 1
    run json 1
    clients
    run binary 64
    run octet 64
    kill "$pid"
    wait "$pid" 2>/dev/null || true
done
