#!/bin/bash
# fresh_container.sh - README's test command as a new user meets it: a clean clone of this
# repository in a fresh Debian 12 container (deploy/base-image.sh's debootstrapped image),
# `.ci/deps` with the network, then `.ci/test` with the network cut (--network=none) and
# 1,024 file descriptors, so a test that fetched anything, or needed more descriptors than a
# default machine gives, fails here. Prints the test command's time; README.md's figure is
# this script's, on an otherwise idle machine.
#
# The container stands in for a machine on which the tests run as root: --privileged gives
# it what root has there (the store's full-disk test mounts a tmpfs in a namespace of its
# own). Needs podman (deploy/base-image.sh installs it). usage: tests/ci/fresh_container.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
deploy/base-image.sh
work=$(mktemp -d)
name=sdfd-fresh-$$
cleanup() {
    podman rm -f "$name" >/dev/null 2>&1 || true
    podman rmi -f "localhost/$name" >/dev/null 2>&1 || true
    rm -rf "$work"
}
trap cleanup EXIT
git clone -q "$PWD" "$work/repo"
podman=(podman --runtime runc)
limits=(--ulimit nofile=1024:1024 --ulimit nproc=4000:4000 --privileged)
# The host's trusted certificates for npm (node's NODE_EXTRA_CA_CERTS), so that a network
# behind a TLS-intercepting proxy, which the host trusts and a fresh container does not,
# still reaches the npm registry.
cas=()
[ ! -f /etc/ssl/certs/ca-certificates.crt ] ||
    cas=(-v /etc/ssl/certs/ca-certificates.crt:/host-ca.crt:ro -e NODE_EXTRA_CA_CERTS=/host-ca.crt)
echo "== fresh_container: .ci/deps in debian:bookworm-slim, with the network"
"${podman[@]}" run "${limits[@]}" "${cas[@]}" --name "$name" --network=host \
    -v "$work/repo:/repo" docker.io/library/debian:bookworm-slim bash -c 'cd /repo && .ci/deps'
"${podman[@]}" commit -q "$name" "localhost/$name" >/dev/null
"${podman[@]}" rm "$name" >/dev/null
echo "== fresh_container: .ci/test, the network cut"
start=$(date +%s)
status=0
"${podman[@]}" run "${limits[@]}" --rm --network=none -v "$work/repo:/repo" "localhost/$name" \
    bash -c 'cd /repo && .ci/test' || status=$?
echo "fresh_container: .ci/test took $(($(date +%s) - start)) s with the network cut," \
    "exit status $status"
exit "$status"
