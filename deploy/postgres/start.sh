#!/bin/bash
# start.sh - the sdfd-postgres container's entry point (postgres.Dockerfile): create the
# cluster on first start (role and database sdfd, password $SDFD_DB_PASSWORD), then run the
# server in the foreground (SIGINT from `podman stop` is PostgreSQL's fast shutdown).
set -euo pipefail
bin=/usr/lib/postgresql/15/bin
if [ ! -s "$PGDATA/PG_VERSION" ]; then
    : "${SDFD_DB_PASSWORD:?set SDFD_DB_PASSWORD: the password of the role sdfd}"
    "$bin/initdb" -D "$PGDATA" -U postgres -A scram-sha-256 -E UTF8 --locale=C.UTF-8 \
        --pwfile=<(head -c 32 /dev/urandom | base64) >/dev/null
    password=${SDFD_DB_PASSWORD//\'/\'\'}
    "$bin/postgres" --single -D "$PGDATA" -c unix_socket_directories= postgres >/dev/null <<SQL
CREATE ROLE sdfd LOGIN PASSWORD '$password';
CREATE DATABASE sdfd OWNER sdfd;
SQL
    echo "sdfd-postgres: created the cluster in $PGDATA"
fi
exec "$bin/postgres" -D "$PGDATA" -c listen_addresses="$PGHOST_ADDR" -c port="$PGPORT" \
    -c unix_socket_directories= -c password_encryption=scram-sha-256
