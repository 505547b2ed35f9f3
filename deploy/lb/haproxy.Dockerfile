# haproxy.Dockerfile - Debian's HAProxy 2.6 with deploy/lb/haproxy.cfg, for the single-machine
# pod (deploy/podman/sdfd-pod.yaml). Its environment variables (SDFD_ROUTING, LB_HTTP, SDFD_1_HTTP,
# ...) are read when it starts; the file says which.
#
#   podman build --isolation=chroot --pull=never --format docker -t sdfd-haproxy \
#       -f deploy/lb/haproxy.Dockerfile .
FROM debian:bookworm-slim
RUN apt-get update -qq \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends haproxy \
    && apt-get clean && rm -rf /var/lib/apt/lists/* /var/cache/apt/* /var/log/* \
    && groupadd --system --gid 10002 sdfd-lb \
    && useradd --system --uid 10002 --gid 10002 --no-create-home --home-dir /nonexistent \
           --shell /usr/sbin/nologin sdfd-lb
COPY deploy/lb/haproxy.cfg /etc/haproxy/sdfd.cfg
USER 10002:10002
EXPOSE 8080 9090
ENTRYPOINT ["/usr/sbin/haproxy", "-db", "-f", "/etc/haproxy/sdfd.cfg"]
