#!/bin/sh
# Tests .ci/test itself: in a temporary copy of the working tree, a broken change must make it
# exit non-zero and never print "0 failed". Three breakages, each in tests/io/test_npy.c:
#   1. a warning (an unused variable), in a copy whose build/ was first set up without
#      --werror the way README's first command does: -Werror must still apply;
#   2. a test that fails (abort at start-up);
#   3. a heap overflow that only AddressSanitizer sees: the sanitizer's report must fail the run.
# And the unbroken copy must pass (so the three failures are the injections' doing).
# Run by .ci/run after the full suite; takes a few minutes (a release and an ASan build).
set -eu
cd "$(dirname "$0")/../.."
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

copy() { # fresh copy of the tracked and new files into $tmp/repo
    rm -rf "$tmp/repo"
    mkdir "$tmp/repo"
    git ls-files -co --exclude-standard -z | xargs -0 tar -cf - | tar -xf - -C "$tmp/repo"
    # and the npm packages .ci/deps installed here, so that its run in the copy fetches nothing
    local d
    for d in tests/server/page deploy/k8s/check tests/api; do
        [ ! -d "$d/node_modules" ] || cp -a "$d/node_modules" "$tmp/repo/$d/"
    done
}

# One copy and one release build serve every case: each injection starts from the pristine
# test file, so only that file is rebuilt between them.
inject() { # C text appended to the pristine test file
    cp tests/io/test_npy.c "$tmp/repo/tests/io/test_npy.c"
    printf '%s\n' "$1" >>"$tmp/repo/tests/io/test_npy.c"
}

expect() { # fail|pass, description, builds: runs .ci/test on npy only
    want=$1 what=$2
    shift 2
    if SDF_CI_BUILDS="$*" SDF_CI_TESTS=npy "$tmp/repo/.ci/test" >"$tmp/log" 2>&1; then
        got=pass
    else
        got=fail
    fi
    tail -n 1 "$tmp/log" | grep -q '^tests: ' || { tail -n 20 "$tmp/log"; got="no summary"; }
    if [ "$got" != "$want" ]; then
        tail -n 30 "$tmp/log"
        echo "FAIL: $what: expected $want, got $got"
        exit 1
    fi
    echo "ok: $what ($(tail -n 1 "$tmp/log"))"
}

copy
(cd "$tmp/repo" && meson setup build --buildtype=release >/dev/null)
expect pass "unchanged tree" release
inject 'static int ci_injected_unused;'
expect fail "a warning in a build/ set up without --werror" release

copy
inject '#include <stdlib.h>
__attribute__((constructor)) static void ci_injected_failure(void) { abort(); }'
expect fail "a failing test" release

copy
inject '#include <stdlib.h>
__attribute__((constructor)) static void ci_injected_overflow(void)
{
    char *p = malloc(4);
    volatile int i = 4;
    p[i] = 1;
    free(p);
}'
expect pass "a heap overflow, release build (unseen)" release
expect fail "a heap overflow, address sanitizer build" asan-unit
echo "test_ci: all passed"
