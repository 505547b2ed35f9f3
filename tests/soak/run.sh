#!/bin/sh
# The soak test (tests/soak/soak.py, docs/robustness.md "Soak"): one sdfd under a mixed load
# for MINUTES (default 2), every answer checked against the library's bits, RSS and
# descriptors checked after warm-up and at the end. Exits non-zero when a check fails.
# Needs a build in $SDF_BUILD (default build/) with sdfd, sdf-bench and sdf-volume.
#
#   tests/soak/run.sh [MINUTES]
set -eu
cd "$(dirname "$0")/../.."
build=${SDF_BUILD:-build}
if [ -f "$build/build.ninja" ]; then
    meson compile -C "$build" sdfd sdf-bench sdf-volume >/dev/null
fi
exec python3 tests/soak/soak.py --minutes "${1:-2}" --build "$build"
