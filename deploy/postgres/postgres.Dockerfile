# postgres.Dockerfile - Debian's PostgreSQL 15 for the single-machine pod's catalog
# (deploy/podman/sdfd-pod.yaml, docs/deploy.md): sdfd's replicas keep their meshes, volumes
# and jobs there (--catalog). Its data lives in a volume mounted at /var/lib/sdfd-postgres;
# the first start creates the cluster there, with the role and database `sdfd` whose password
# is $SDFD_DB_PASSWORD, and later starts reuse it. It listens on $PGHOST_ADDR:$PGPORT
# (default 127.0.0.1:5432) with password (scram-sha-256) authentication, and on no Unix
# socket, so the root file system can stay read-only.
#
#   podman build --isolation=chroot --pull=never --format docker -t sdfd-postgres \
#       -f deploy/postgres/postgres.Dockerfile .
FROM debian:bookworm-slim
RUN groupadd --system --gid 10003 postgres \
    && useradd --system --uid 10003 --gid 10003 --home-dir /var/lib/postgresql \
           --shell /bin/sh postgres \
    && apt-get update -qq \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
           postgresql-15 \
    && apt-get clean && rm -rf /var/lib/apt/lists/* /var/cache/apt/* /var/log/* \
    && install -d -o 10003 -g 10003 -m 0700 /var/lib/sdfd-postgres
COPY deploy/postgres/start.sh /usr/local/bin/sdfd-postgres
USER 10003:10003
ENV PGDATA=/var/lib/sdfd-postgres/data PGHOST_ADDR=127.0.0.1 PGPORT=5432
STOPSIGNAL SIGINT
ENTRYPOINT ["/usr/local/bin/sdfd-postgres"]
