#!/bin/sh
# Runs every libFuzzer harness of tests/fuzz/, one after the other, for SECONDS each.
#
#   tests/fuzz/run.sh [SECONDS [RUNS]]
#
# SECONDS (default 30; 0 = no time limit) is each harness's -max_total_time; RUNS (default: no
# limit) its -runs, the executions after which it stops (docs/robustness.md: the long run is
# `tests/fuzz/run.sh 0 10000000`). FUZZ_HARNESSES="proto url" runs only those.
#
# Sets up build-fuzz (clang, -Dfuzz=true: address and undefined-behaviour sanitizers, every
# report fatal) if it does not exist, and builds the harnesses. Each harness starts from its
# seed corpus and regression inputs (tests/fuzz/corpus/, regressions/; never written to) and
# keeps what it finds in build-fuzz/fuzz-corpus/<harness>/, so later runs go on from there;
# a crash, leak or timeout input is written to build-fuzz/fuzz-artifacts/<harness>/ and its
# log kept as build-fuzz/fuzz-logs/<harness>.log. Options: -timeout=10 (seconds for one input)
# -malloc_limit_mb=2048 (the largest single allocation) and -rss_limit_mb=4096 (the whole
# process, whose sanitizer bookkeeping grows over millions of executions: docs/robustness.md),
# with the harness's dictionary.
#
# Prints one line per harness (executions, exec/s, coverage as libFuzzer counts it: cov edges
# and ft features, the corpus, the verdict) and `fuzz: N passed, N failed`; exits non-zero if
# any harness crashed, leaked, timed out or ran out of memory.
set -eu
cd "$(dirname "$0")/../.."
seconds=${1:-30}
runs=${2:--1}
build=build-fuzz
harnesses=${FUZZ_HARNESSES:-"mesh_obj mesh_ply mesh_stl mesh_off mesh_auto npy body_npy exr proto
    json_query json_filter json_bake url mesh_arrays"}

if [ ! -f "$build/build.ninja" ]; then
    CC=clang meson setup "$build" --buildtype=debugoptimized -Dfuzz=true --werror >/dev/null
fi
targets=""
for h in $harnesses; do
    targets="$targets tests/fuzz/fuzz-$h"
done
ninja -C "$build" $targets >"$build/fuzz-build.log" 2>&1 ||
    { cat "$build/fuzz-build.log" >&2; exit 1; }

dict_of() {
    case "$1" in
        mesh_obj) echo obj ;; mesh_ply) echo ply ;; mesh_stl) echo stl ;; mesh_off) echo off ;;
        mesh_auto) echo mesh ;; npy|body_npy) echo npy ;; exr) echo exr ;; proto) echo proto ;;
        json_*) echo json ;; url) echo url ;; mesh_arrays) echo arrays ;;
    esac
}

# The value of libFuzzer's `name: value` or `stat::name: value` in a log's last such line.
field() { # log name
    grep -o "$2: *[0-9]*" "$1" | tail -1 | sed 's/.*: *//'
}

passed=0 failed=0
printf '%-12s %10s %8s %6s %6s %6s  %s\n' harness execs exec/s cov ft corpus result
for h in $harnesses; do
    work="$build/fuzz-corpus/$h" art="$build/fuzz-artifacts/$h" log="$build/fuzz-logs/$h.log"
    mkdir -p "$work" "$art" "$build/fuzz-logs"
    set -- "tests/fuzz/corpus/$h"
    [ -d "tests/fuzz/regressions/$h" ] && set -- "$@" "tests/fuzz/regressions/$h"
    rc=0
    "$build/tests/fuzz/fuzz-$h" -max_total_time="$seconds" -runs="$runs" -timeout=10 \
        -malloc_limit_mb=2048 -rss_limit_mb=4096 -dict="tests/fuzz/dict/$(dict_of "$h").dict" \
        -print_final_stats=1 -artifact_prefix="$art/" "$work" "$@" >"$log" 2>&1 || rc=$?
    result=ok
    if [ "$rc" -ne 0 ]; then
        result="FAILED (exit $rc)"
        for kind in "libFuzzer: timeout" "libFuzzer: out-of-memory" "LeakSanitizer" \
            "AddressSanitizer" "runtime error" "libFuzzer: deadly signal"; do
            if grep -q "$kind" "$log"; then
                result="FAILED: $kind, see $log"
                break
            fi
        done
        failed=$((failed + 1))
    else
        passed=$((passed + 1))
    fi
    printf '%-12s %10s %8s %6s %6s %6s  %s\n' "$h" \
        "$(field "$log" stat::number_of_executed_units)" \
        "$(field "$log" stat::average_exec_per_sec)" "$(field "$log" cov)" "$(field "$log" ft)" \
        "$(grep -o 'corp: [0-9]*' "$log" | tail -1 | sed 's/corp: //')" "$result"
done
echo "fuzz: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
