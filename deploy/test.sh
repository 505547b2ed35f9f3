#!/bin/bash
# test.sh - tests what deploy/ ships, on one Debian 12 machine with no container registry:
#   lb     HAProxy and nginx (deploy/lb/) in both routing modes in front of 3 sdfd replicas
#          sharing one PostgreSQL catalog: meshes uploaded and a volume baked through the
#          balancer are answered by every replica; under load, one replica SIGKILLed and
#          restarted, another SIGTERMed, while a writer PUTs and DELETEs: no failed request,
#          every answer equal to a reference sdfd's, every acknowledged write kept
#          (deploy/failover.py, deploy/shared_store.py)
#   image  deploy/Dockerfile built from a clean copy of the repository (git ls-files): size,
#          a query, the HEALTHCHECK, a drain on `podman stop`, non-root, read-only root, a
#          store on a volume that outlives the container
#   k8s    deploy/k8s/ passes yamllint and two schema checks, and broken manifests fail them
#   pod    deploy/podman/sdfd-pod.yaml under `podman kube play` (two replicas, HAProxy and
#          PostgreSQL): a mesh uploaded and a volume baked through HAProxy answer through it
#          and on each replica as sdfd's own, and again after the pod is replaced
#
#   deploy/test.sh [PART...]       (default: all four; run as root)
#
# It installs the Debian packages it needs (apt), builds build/server/sdfd if missing, and
# makes the Debian base image with deploy/base-image.sh if missing; the npm packages of
# deploy/k8s/check (kubernetes-models) come from .ci/deps. Ends with `deploy: N passed, N failed`.
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
        return 1
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

# sdfd, and failover.py's C binary worker (sdfc-load, libsdfclient).
sdfd_binary() {
    if [ ! -x build/server/sdfd ] || [ ! -x build/tests/sdfc-load ]; then
        .ci/deps
        [ -f build/build.ninja ] || meson setup build --buildtype=release >/dev/null
        meson compile -C build sdfd sdfc-load >/dev/null
    fi
}

part_lb() {
    deps haproxy nginx-light libnginx-mod-stream python3-numpy postgresql
    command -v node >/dev/null || deps nodejs # failover.py's JS binary worker
    sdfd_binary
    check "haproxy.cfg parses" haproxy -c -q -f deploy/lb/haproxy.cfg
    local lb mode
    for lb in haproxy nginx; do
        for mode in leastconn hash; do
            check "failover: $lb, $mode" $PY deploy/failover.py --lb "$lb" --mode "$mode"
        done
    done
}

IMAGE=localhost/sdfd:latest
# Without systemd, podman logs "unable to get systemd connection" for the HEALTHCHECK's timer
# (harmless: `podman healthcheck run` runs the check); those lines are filtered out.
PODMAN_RUN=(podman_quiet --runtime runc run --network=host --ulimit nofile=1024:1024
            --ulimit nproc=1000:1000)

podman_quiet() {
    podman "$@" 2> >(grep -v "unable to get systemd connection" >&2)
}

free_port() {
    $PY -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

wait_ready() { # url, seconds: polls /readyz until 200
    local deadline=$((SECONDS + $2))
    until curl -sf -o /dev/null "$1/readyz"; do
        [ $SECONDS -lt $deadline ] || return 1
        sleep 0.1
    done
}

same_answer() { # url-a, url-b, mesh: one JSON and one octet-stream query answer the same bytes
    $PY - "$@" <<'PYEOF'
import sys, urllib.request, json
import numpy as np
a, b, mesh = sys.argv[1:4]
pts = np.random.default_rng(3).uniform(-2, 2, (2000, 3)).astype(np.float32)
bodies = [("application/json", json.dumps({"points": pts.tolist(), "mode": "gradient"}).encode(), ""),
          ("application/octet-stream", pts.tobytes(), "?mode=closest")]
for ctype, body, query in bodies:
    answers = []
    for url in (a, b):
        r = urllib.request.Request(f"{url}/v1/meshes/{mesh}/query{query}", body,
                                   {"Content-Type": ctype})
        answers.append(urllib.request.urlopen(r, timeout=60).read())
    if answers[0] != answers[1] or len(answers[0]) < 2000:
        sys.exit(f"{ctype}: the answers differ ({len(answers[0])} and {len(answers[1])} bytes)")
PYEOF
}

build_image() { # [dockerfile image]
    local file=${1:-deploy/Dockerfile} image=${2:-$IMAGE}
    deps podman runc debootstrap uidmap python3-numpy curl
    deploy/base-image.sh
    local src
    src=$(mktemp -d)
    # a clean copy: the tracked (and new, unignored) files only, no build directories
    git ls-files -co --exclude-standard -z | while IFS= read -r -d '' f; do
        [ -e "$f" ] && printf '%s\0' "$f"
    done | xargs -0 tar -cf - | tar -xf - -C "$src"
    podman build --isolation=chroot --pull=never --format docker -t "$image" \
        -f "$file" "$src" >"$src.log" 2>&1
    local rc=$?
    [ $rc -eq 0 ] || tail -n 30 "$src.log"
    rm -rf "$src" "$src.log"
    return $rc
}

part_image() {
    check "the image builds from a clean copy" build_image || return
    sdfd_binary
    local size
    size=$(podman image inspect "$IMAGE" --format '{{.Size}}')
    echo "image size: $((size / 1000000)) MB"
    check "the image is under 200 MB" test "$size" -lt 200000000
    check "the image runs as uid 10001 with an exec-form entrypoint" test \
        "$(podman image inspect "$IMAGE" --format '{{.Config.User}} {{.Config.Entrypoint}}')" \
        = "10001:10001 [/usr/local/bin/sdfd]"

    local name=sdfd-test-$$ http bin ref refpid t0
    http=$(free_port) bin=$(free_port) ref=$(free_port)
    t0=$(date +%s%N)
    "${PODMAN_RUN[@]}" -d --name "$name" --read-only \
        -e SDFD_HTTP=127.0.0.1:$http -e SDFD_BIN=127.0.0.1:$bin "$IMAGE" >/dev/null
    check "the container becomes ready" wait_ready "http://127.0.0.1:$http" 60
    echo "cold start to ready: $(( ($(date +%s%N) - t0) / 1000000 )) ms"
    build/server/sdfd --http 127.0.0.1:$ref --bin 127.0.0.1:$(free_port) 2>/dev/null &
    refpid=$!
    wait_ready "http://127.0.0.1:$ref" 30
    check "the demo mesh answers as the host build does" \
        same_answer "http://127.0.0.1:$http" "http://127.0.0.1:$ref" demo
    kill "$refpid"
    wait "$refpid"
    check "podman healthcheck run: healthy" podman healthcheck run "$name"
    check "the health check fails on a port nothing listens on" \
        bash -c "! podman exec -e SDFD_HTTP=127.0.0.1:1 $name sdfd-healthcheck 2>/dev/null"
    check "sdfd runs as uid 10001" test \
        "$(podman exec "$name" awk '/^Uid:/ {print $2}' /proc/1/status)" = 10001
    check "the root file system is read-only" \
        bash -c "! podman exec $name sh -c ': >/probe' 2>/dev/null"
    check "podman stop exits 0" bash -c "podman stop -t 40 $name 2>/dev/null >/dev/null"
    check "sdfd exited 0" test "$(podman inspect "$name" --format '{{.State.ExitCode}}')" = 0
    check "the drain is logged" bash -c "podman logs $name 2>&1 | grep -q 'SIGTERM: draining' &&
        podman logs $name 2>&1 | grep -q '\"event\":\"stopped\"'"
    podman_quiet rm -f "$name" >/dev/null

    # meshes from a read-only volume, as every replica gets them (docs/deploy.md)
    local meshes
    meshes=$(mktemp -d)
    cp tests/data/fandisk.off tests/data/refined_elephant.off "$meshes"
    chmod -R a+rX "$meshes"
    http=$(free_port) bin=$(free_port) ref=$(free_port)
    t0=$(date +%s%N)
    "${PODMAN_RUN[@]}" -d --name "$name" --read-only -v "$meshes:/meshes:ro" \
        -e SDFD_HTTP=127.0.0.1:$http -e SDFD_BIN=127.0.0.1:$bin "$IMAGE" --mesh-dir /meshes \
        >/dev/null
    check "the container loads meshes from a read-only volume" \
        wait_ready "http://127.0.0.1:$http" 120
    echo "cold start to ready with refined_elephant and fandisk: $(( ($(date +%s%N) - t0) / 1000000 )) ms"
    build/server/sdfd --http 127.0.0.1:$ref --bin 127.0.0.1:$(free_port) \
        --mesh-dir "$meshes" 2>/dev/null &
    refpid=$!
    wait_ready "http://127.0.0.1:$ref" 120
    check "refined_elephant answers as the host build does" \
        same_answer "http://127.0.0.1:$http" "http://127.0.0.1:$ref" refined_elephant
    kill "$refpid"
    wait "$refpid"
    podman_quiet rm -f -t 0 "$name" >/dev/null
    image_store "$meshes" "$name"
    rm -rf "$meshes"
}

# The image with a store (SDFD_DATA_DIR) on a host directory: an upload outlives the container,
# and the HEALTHCHECK fails while the store is unreadable.
image_store() { # meshes-dir container-name
    local meshes=$1 name=$2 data http ref refpid
    data=$(mktemp -d)
    chown 10001:10001 "$data"
    http=$(free_port) ref=$(free_port)
    store_container() { # starts the container on $data
        "${PODMAN_RUN[@]}" -d --name "$name" --read-only -v "$data:/data" \
            -e SDFD_DATA_DIR=/data -e SDFD_HTTP=127.0.0.1:$http \
            -e SDFD_BIN=127.0.0.1:$(free_port) "$IMAGE" >/dev/null
    }
    store_container
    check "the container becomes ready on an empty store" wait_ready "http://127.0.0.1:$http" 60
    check "with a store and no mesh flags it serves no mesh" \
        test "$(curl -sf "http://127.0.0.1:$http/v1/meshes")" = '{"meshes":[]}'
    check "a mesh PUT to the container is stored in the volume" bash -c \
        "curl -sf -o /dev/null -X PUT --data-binary @$meshes/fandisk.off \
         'http://127.0.0.1:$http/v1/meshes/fandisk?format=off' && test -s $data/meshes/fandisk.json"
    podman_quiet rm -f -t 10 "$name" >/dev/null
    build/server/sdfd --http 127.0.0.1:$ref --bin 127.0.0.1:$(free_port) \
        --mesh-dir "$meshes" 2>/dev/null &
    refpid=$!
    store_container
    check "a new container on the same store becomes ready" \
        wait_ready "http://127.0.0.1:$http" 60
    wait_ready "http://127.0.0.1:$ref" 60
    check "a new container serves it from the store, as the host build does" \
        same_answer "http://127.0.0.1:$http" "http://127.0.0.1:$ref" fandisk
    kill "$refpid"
    wait "$refpid"
    chmod 000 "$data"
    sleep 1.5
    check "the health check fails while the store is unreadable" bash -c \
        "curl -s http://127.0.0.1:$http/readyz | grep -q 'store unreadable' &&
         ! podman healthcheck run $name >/dev/null 2>&1"
    chmod 700 "$data"
    sleep 1.5
    check "and passes again once it is readable" podman healthcheck run "$name"
    podman_quiet rm -f -t 0 "$name" >/dev/null
    rm -rf "$data"
}

# Copies of deploy/k8s, each broken one way, for the checks to refuse.
broken_manifests() { # dir
    local k
    for k in kustomize memory no-catalog rwx data-dir pg-service pg-password; do
        mkdir "$1/$k"
        cp -r deploy/k8s/kustomization.yaml deploy/k8s/base deploy/k8s/postgres \
            deploy/k8s/with-postgres "$1/$k"
    done
    $PY - "$1" <<'PYEOF'
import sys, yaml
out = sys.argv[1]
base = yaml.safe_load(open("deploy/k8s/base/deployment.yaml"))
def save(path, doc):
    yaml.safe_dump(doc, open(f"{out}/{path}", "w"), sort_keys=False)
d = yaml.safe_load(yaml.safe_dump(base))
c = d["spec"]["template"]["spec"]["containers"][0]
c["readinessprobe"] = c.pop("readinessProbe")  # a misspelt field
save("unknown-field.yaml", d)
d = yaml.safe_load(yaml.safe_dump(base))
del d["spec"]["template"]["spec"]["containers"][0]["name"]  # a required field
save("missing-field.yaml", d)
# the catalog's Secret gone
k = yaml.safe_load(open(f"{out}/no-catalog/base/kustomization.yaml"))
k["resources"].remove("catalog-secret.yaml")
save("no-catalog/base/kustomization.yaml", k)
# a ReadWriteMany claim mounted, as the replicas once shared a data directory
k = yaml.safe_load(open(f"{out}/rwx/base/kustomization.yaml"))
k["resources"].append("pvc.yaml")
save("rwx/base/kustomization.yaml", k)
save("rwx/base/pvc.yaml", {"apiVersion": "v1", "kind": "PersistentVolumeClaim",
                           "metadata": {"name": "sdfd-data"},
                           "spec": {"accessModes": ["ReadWriteMany"],
                                    "resources": {"requests": {"storage": "10Gi"}}}})
d = yaml.safe_load(yaml.safe_dump(base))
pod = d["spec"]["template"]["spec"]
pod["volumes"].append({"name": "data", "persistentVolumeClaim": {"claimName": "sdfd-data"}})
pod["containers"][0]["volumeMounts"].append({"name": "data", "mountPath": "/data"})
save("rwx/base/deployment.yaml", d)
# the local copies' directory on no emptyDir (the root file system, read-only)
d = yaml.safe_load(yaml.safe_dump(base))
for e in d["spec"]["template"]["spec"]["containers"][0]["env"]:
    if e["name"] == "SDFD_DATA_DIR":
        e["value"] = "/data"
save("data-dir/base/deployment.yaml", d)
# the PostgreSQL StatefulSet's serviceName no Service
s = yaml.safe_load(open("deploy/k8s/postgres/statefulset.yaml"))
s["spec"]["serviceName"] = "postgres"
save("pg-service/postgres/statefulset.yaml", s)
# the catalog URI's password not PostgreSQL's
s = yaml.safe_load(open("deploy/k8s/postgres/secret.yaml"))
s["stringData"]["password"] = "another"
save("pg-password/postgres/secret.yaml", s)
PYEOF
    printf 'apiVersion: v1\nkind: ConfigMap\nmetadata:\n  name: a\n  name: b\n' >"$1/lint.yaml"
    sed -i 's/terminationGracePeriodSeconds: .*/terminationGracePeriodSeconds: 25/' \
        "$1/kustomize/base/deployment.yaml"
    sed -i 's/memory: 1Gi/memory: 768Mi/' "$1/memory/base/deployment.yaml"
}

part_k8s() {
    deps yamllint python3-kubernetes python3-yaml
    command -v node >/dev/null || deps nodejs npm
    # kubernetes-models: .ci/deps installs it from the committed lock file
    cmp -s deploy/k8s/check/package-lock.json deploy/k8s/check/node_modules/.installed-lock.json ||
        { echo "deploy/k8s/check/node_modules is missing or was not installed from" \
               "package-lock.json: run .ci/deps (it runs npm ci there)"
          check "deploy/k8s/check/node_modules from package-lock.json" false; return; }
    shopt -s nullglob
    local manifests=(deploy/k8s/*.yaml deploy/k8s/{base,postgres,with-postgres}/*.yaml
                     deploy/podman/*.yaml) bad
    local cm="$PY deploy/k8s/check/check_manifests.py"
    check "yamllint" yamllint -s -c deploy/k8s/check/yamllint.yaml "${manifests[@]}"
    check "kubernetes-models: types and required fields" \
        node deploy/k8s/check/validate.mjs "${manifests[@]}"
    check "python3-kubernetes: no unknown field; deploy/k8s hangs together" \
        $cm --kustomize deploy/k8s
    check "python3-kubernetes: no unknown field; deploy/k8s/with-postgres hangs together" \
        $cm --kustomize deploy/k8s/with-postgres
    [ ! -e deploy/podman ] || check "python3-kubernetes: no unknown field in deploy/podman" \
        $cm deploy/podman/*.yaml
    bad=$(mktemp -d)
    broken_manifests "$bad"
    refused() { # description, directory, what the check must say
        check "$1 fails the kustomize check" bash -c \
            "if $cm --kustomize $2 >$bad/out; then echo 'it passed'; false;
             else grep -qF -- '$3' $bad/out || { cat $bad/out; false; }; fi"
    }
    check "an unknown field fails the field check" \
        bash -c "! $cm $bad/unknown-field.yaml"
    check "a missing required field fails kubernetes-models" \
        bash -c "! node deploy/k8s/check/validate.mjs $bad/missing-field.yaml"
    check "a duplicate key fails yamllint" \
        bash -c "! yamllint -s -c deploy/k8s/check/yamllint.yaml $bad/lint.yaml >/dev/null"
    refused "a grace period shorter than preStop + drain" "$bad/kustomize" \
        "terminationGracePeriodSeconds is not above"
    refused "a memory limit under the budgets" "$bad/memory" "memory limit 768Mi under"
    refused "no catalog Secret" "$bad/no-catalog" "no Secret sdfd-catalog with key catalog"
    refused "a ReadWriteMany volume" "$bad/rwx" "volume data: a ReadWriteMany claim"
    refused "SDFD_DATA_DIR on no emptyDir" "$bad/data-dir" \
        "SDFD_DATA_DIR /data is not the mount of an emptyDir"
    refused "a PostgreSQL StatefulSet without its Service" "$bad/pg-service/with-postgres" \
        "no Service postgres (its serviceName)"
    refused "a catalog URI with another password than PostgreSQL's" \
        "$bad/pg-password/with-postgres" "password is not that of StatefulSet sdfd-postgres"
    check "the unbroken copy passes the kustomize check, with PostgreSQL too" bash -c \
        "sed -i 's/terminationGracePeriodSeconds: 25/terminationGracePeriodSeconds: 40/' \
         $bad/kustomize/base/deployment.yaml && $cm --kustomize $bad/kustomize &&
         $cm --kustomize $bad/kustomize/with-postgres"
    rm -rf "$bad"
}

# deploy/podman/sdfd-pod.yaml with free ports for its seven, and a pod name and a volume (its
# PostgreSQL's data) of its own.
render_pod() { # out-file pod-name
    $PY - "$1" "$2" <<'PYEOF'
import re, socket, sys
out, name = sys.argv[1:3]
text = open("deploy/podman/sdfd-pod.yaml").read()
ports = {}
for p in ("8080", "9090", "8081", "9091", "8082", "9092", "5432"):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    ports[p] = str(s.getsockname()[1])
    s.close()
text = re.sub(r"\b(8080|9090|8081|9091|8082|9092|5432)\b", lambda m: ports[m.group(1)], text)
text = text.replace("\n  name: sdfd\n", f"\n  name: {name}\n", 1)
if text.count("claimName: sdfd-data\n") != 1:
    sys.exit("sdfd-pod.yaml: expected one claimName: sdfd-data")
text = text.replace("claimName: sdfd-data\n", f"claimName: {name}-data\n")
open(out, "w").write(text)
print(" ".join(ports[p] for p in ("8080", "9090", "8081", "8082")))
PYEOF
}

kube_play() { # [--down] file: podman kube play, quiet unless it fails
    local out rc
    out=$(CONTAINERS_CONF=$ROOT/deploy/podman/containers.conf podman kube play "$@" 2>&1)
    rc=$?
    [ $rc -eq 0 ] || grep -v "unable to get systemd connection" <<<"$out"
    return $rc
}

served_points() { # url: sdfd_points_total from a replica's /metrics
    curl -sf "$1/metrics" | awk '$1 == "sdfd_points_total" {print $2}'
}

part_pod() {
    deps catatonit # podman's pause container
    check "the sdfd image builds" build_image || return
    check "the haproxy image builds" build_image deploy/lb/haproxy.Dockerfile \
        localhost/sdfd-haproxy:latest || return
    check "the postgres image builds" build_image deploy/postgres/postgres.Dockerfile \
        localhost/sdfd-postgres:latest || return
    local yaml name=sdfd-test-$$ lb lbbin r1 r2 meshes ref refpid
    yaml=$(mktemp --suffix .yaml)
    read -r lb lbbin r1 r2 < <(render_pod "$yaml" "$name")
    # the reference: the host build, loading the same files itself
    meshes=$(mktemp -d)
    cp tests/data/fandisk.off tests/data/cow.off tests/data/knot1.off "$meshes"
    ref=$(free_port)
    build/server/sdfd --http 127.0.0.1:$ref --bin 127.0.0.1:$(free_port) --mesh-dir "$meshes" \
        2>/dev/null &
    refpid=$!
    wait_ready "http://127.0.0.1:$ref" 60
    check "podman kube play starts the pod" kube_play "$yaml"
    pod_ready "$lb" "$r1" "$r2"
    check "through HAProxy: a mesh uploaded and a volume baked answer there and on each replica as sdfd's own; a replacement and a delete reach both replicas" \
        $PY deploy/shared_store.py --lb "http://127.0.0.1:$lb" --reference "http://127.0.0.1:$ref" \
        --replica "http://127.0.0.1:$r1" --replica "http://127.0.0.1:$r2" \
        --mesh "fandisk=$meshes/fandisk.off" --swap "cow=$meshes/cow.off" \
        "knot1=$meshes/knot1.off"
    check "answers through HAProxy equal sdfd's own" \
        same_answer "http://127.0.0.1:$lb" "http://127.0.0.1:$ref" fandisk
    check "a load through HAProxy: every answer equal to sdfd's own" $PY deploy/loadgen.py \
        --target "http://127.0.0.1:$lb" --reference "http://127.0.0.1:$ref" --meshes fandisk \
        --volumes fandisk-sdf --workers 4 --seconds 4
    check "both replicas served queries" bash -c \
        "[ \"\$($(declare -f served_points); served_points http://127.0.0.1:$r1)\" -gt 0 ] &&
         [ \"\$($(declare -f served_points); served_points http://127.0.0.1:$r2)\" -gt 0 ]"
    check "the binary port through HAProxy answers as sdfd does" $PY -c "
import sys, numpy as np
sys.path.insert(0, 'clients/python')
import sdfclient
p = np.random.default_rng(5).uniform(-2, 2, (3000, 3)).astype(np.float32)
a = sdfclient.BinaryClient('127.0.0.1', $lbbin).query('fandisk', p, mode='closest')
b = sdfclient.Client('http://127.0.0.1:$ref').query('fandisk', p, mode='closest')
sys.exit(any(np.asarray(a[k]).tobytes() != np.asarray(b[k]).tobytes() for k in b))"
    check "podman kube play --down stops it" kube_play --down "$yaml"
    # a new pod on the same volume serves what the first one stored
    kube_play "$yaml"
    pod_ready "$lb" "$r1" "$r2"
    check "a new pod on the same volume answers the upload through HAProxy as sdfd does" \
        same_answer "http://127.0.0.1:$lb" "http://127.0.0.1:$ref" fandisk
    check "... and the baked volume" $PY deploy/loadgen.py --target "http://127.0.0.1:$lb" \
        --reference "http://127.0.0.1:$ref" --meshes "" --volumes fandisk-sdf --workers 2 \
        --seconds 1 --requests 8
    kube_play --down "$yaml"
    check "the pod's volume is removed" bash -c "podman volume rm $name-data >/dev/null"
    kill "$refpid"
    wait "$refpid"
    rm -rf "$yaml" "$meshes"
}

pod_ready() { # lb-port replica-ports...
    local lb=$1
    shift
    check "both replicas become ready" bash -c "$(declare -f wait_ready); for p in $*; do
        wait_ready http://127.0.0.1:\$p 60 || exit 1; done"
    check "HAProxy in the pod answers" wait_ready "http://127.0.0.1:$lb" 30
}

for part in $parts; do
    case "$part" in
        lb|image|k8s|pod) echo "== $part"; "part_$part" ;;
        *) echo "unknown part '$part' (lb, image, k8s, pod)" >&2; exit 2 ;;
    esac
done
echo "deploy: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
