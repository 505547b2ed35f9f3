#!/bin/sh
# The gcc and clang builds give the same answers, byte for byte: sdf-bench's outputs on several
# meshes, workloads, modes, sign methods and both traversals, and sdf-volume's bakes and
# lookups, from a gcc release build and a clang release build of the same tree. The library's
# answers are decided by double-precision code in ISO C's unfused arithmetic (lib/meson.build,
# core/simd.h), so nothing about them may depend on the compiler; this is the check.
#
#   tests/ci/compilers.sh [GCC_BUILD [CLANG_BUILD]]     (defaults: build, build-clang)
#
# Each build directory is set up (release, --werror) if it does not exist yet, and brought up
# to date. Needs clang (Debian: clang). Prints one line per comparison and
# `compilers: N passed, N failed`; exits non-zero if any output differs or a run fails.
set -eu
cd "$(dirname "$0")/../.."
gcc_dir=${1:-build}
clang_dir=${2:-build-clang}
data=tests/data
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

setup() { # dir compiler
    if [ ! -f "$1/build.ninja" ]; then
        CC=$2 meson setup "$1" --buildtype=release --werror >"$tmp/setup.log" 2>&1 ||
            { cat "$tmp/setup.log" >&2; exit 1; }
    fi
    meson compile -C "$1" sdf-bench sdf-volume >"$tmp/compile.log" 2>&1 ||
        { cat "$tmp/compile.log" >&2; exit 1; }
}
setup "$gcc_dir" gcc
setup "$clang_dir" clang
# A directory set up earlier with another compiler would compare a build with itself.
for pair in "$gcc_dir gcc" "$clang_dir clang"; do
    set -- $pair
    grep -q "C compiler for the host machine: .*($2 " "$1/meson-logs/meson-log.txt" ||
        { echo "compilers: $1 is not a $2 build" >&2; exit 1; }
done

passed=0 failed=0
verdict() { # name, 0 if same
    if [ "$2" -eq 0 ]; then
        passed=$((passed + 1))
        echo "same     $1"
    else
        failed=$((failed + 1))
        echo "DIFFERS  $1"
    fi
}

# One sdf-bench case: a name and its arguments after the mesh; runs both builds, compares.
bench() { # name mesh args...
    case_name=$1 case_mesh=$2
    shift 2
    ok=0
    for b in gcc clang; do
        eval "dir=\$${b}_dir"
        "$dir/tests/bench/sdf-bench" "$case_mesh" "$@" --out "$tmp/$b.npy" >"$tmp/$b.log" 2>&1 ||
            { cat "$tmp/$b.log" >&2; ok=1; }
    done
    [ "$ok" -eq 0 ] && { cmp -s "$tmp/gcc.npy" "$tmp/clang.npy" || ok=1; }
    verdict "$case_name" "$ok"
}

n=200000
for mesh in fandisk.off bear.off knot1.off Spider_binary.stl spider.obj cube.ply \
    elephant-with-holes.off; do
    for w in band box grid; do
        bench "$mesh $w signed" "$data/$mesh" --workload "$w" --n "$n"
    done
    bench "$mesh band gradient" "$data/$mesh" --workload band --n "$n" --mode gradient
    bench "$mesh band closest" "$data/$mesh" --workload band --n "$n" --mode closest
    bench "$mesh box distance single" "$data/$mesh" --workload box --n "$n" --mode distance \
        --traversal single
done
for s in winding raycast; do
    bench "elephant-with-holes.off box $s" "$data/elephant-with-holes.off" --workload box \
        --n "$n" --sign "$s"
done
bench "fandisk.off band filtered" "$data/fandisk.off" --workload band --n 20000 --mode filtered
bench "fandisk.off band filtered-gradient" "$data/fandisk.off" --workload band --n 20000 \
    --mode filtered-gradient

# sdf-volume: a bake by the scan (order 0) and one by the queries (order 1, packed), each
# written as .npy and compared, then a lookup in the EXR of each build.
volume() { # name args after MESH OUT
    name=$1
    shift
    ok=0
    for b in gcc clang; do
        eval "dir=\$${b}_dir"
        "$dir/tests/bench/sdf-volume" bake "$data/fandisk.off" "$tmp/$b.vol" "$@" \
            >"$tmp/$b.json" 2>"$tmp/$b.log" || { cat "$tmp/$b.log" >&2; ok=1; }
    done
    [ "$ok" -eq 0 ] && { cmp -s "$tmp/gcc.vol" "$tmp/clang.vol" || ok=1; }
    verdict "volume $name" "$ok"
}
volume "order 0 npy" --format npy --resolution 48 --order 0
volume "order 1 packed32 npy" --format npy --resolution 40 --order 1 --encoding packed32
volume "order 0 exr" --format exr --resolution 32 --order 0
cp "$tmp/gcc.vol" "$tmp/volume.exr"
ok=0
python3 -c "
import random, struct, sys
n = 50000
head = \"{'descr': '<f4', 'fortran_order': False, 'shape': (%d, 3), }\" % n
head += ' ' * (118 - len(head)) + '\\n'
rng = random.Random(7)
with open(sys.argv[1], 'wb') as f:
    f.write(b'\\x93NUMPY\\x01\\x00' + struct.pack('<H', len(head)) + head.encode())
    f.write(struct.pack('<%df' % (3 * n), *(rng.uniform(-1, 1) for _ in range(3 * n))))
" "$tmp/points.npy" || ok=1
for b in gcc clang; do
    eval "dir=\$${b}_dir"
    "$dir/tests/bench/sdf-volume" eval "$tmp/volume.exr" "$tmp/points.npy" "$tmp/$b-eval.npy" \
        --gradient >"$tmp/$b.log" 2>&1 || { cat "$tmp/$b.log" >&2; ok=1; }
done
[ "$ok" -eq 0 ] && { cmp -s "$tmp/gcc-eval.npy" "$tmp/clang-eval.npy" || ok=1; }
verdict "volume eval gradient" "$ok"

# The field operations (lib/field) on the order-0 EXR, by each solver.
for solver in sussman sweep; do
    ok=0
    for b in gcc clang; do
        eval "dir=\$${b}_dir"
        "$dir/tests/bench/sdf-volume" ops "$tmp/volume.exr" "$tmp/$b-ops.npy" --format npy \
            --solver "$solver" --op smooth=0.05 --op offset=-0.02 >"$tmp/$b.log" 2>&1 ||
            { cat "$tmp/$b.log" >&2; ok=1; }
    done
    [ "$ok" -eq 0 ] && { cmp -s "$tmp/gcc-ops.npy" "$tmp/clang-ops.npy" || ok=1; }
    verdict "volume ops $solver" "$ok"
done

# A first-order EXR looked up by its default reconstruction (tricubic Hermite).
volume "order 1 exr" --format exr --resolution 24 --order 1
cp "$tmp/gcc.vol" "$tmp/volume1.exr"
ok=0
for b in gcc clang; do
    eval "dir=\$${b}_dir"
    "$dir/tests/bench/sdf-volume" eval "$tmp/volume1.exr" "$tmp/points.npy" \
        "$tmp/$b-eval1.npy" --gradient --interpolation hermite >"$tmp/$b.log" 2>&1 ||
        { cat "$tmp/$b.log" >&2; ok=1; }
done
[ "$ok" -eq 0 ] && { cmp -s "$tmp/gcc-eval1.npy" "$tmp/clang-eval1.npy" || ok=1; }
verdict "volume eval order 1 hermite" "$ok"

echo "compilers: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
