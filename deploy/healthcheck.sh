#!/bin/bash
# healthcheck.sh - the container's HEALTHCHECK: exit 0 if sdfd's /readyz answers 200.
# It asks the address sdfd listens on (SDFD_HTTP, the image's way to set it; a wildcard host
# is reached on loopback), so moving the port moves the check. bash's /dev/tcp does the
# request: the image carries no HTTP client.
addr=${SDFD_HTTP:-127.0.0.1:8080}
port=${addr##*:}
host=${addr%:*}
host=${host#[}
host=${host%]}
case "$host" in
    0.0.0.0|"") host=127.0.0.1 ;;
    ::) host=::1 ;;
esac
exec 3<>"/dev/tcp/$host/$port" || exit 1
printf 'GET /readyz HTTP/1.0\r\nHost: %s\r\n\r\n' "$host" >&3
read -r -t 3 status <&3 || exit 1
[[ $status == "HTTP/1."[01]" 200 "* ]]
