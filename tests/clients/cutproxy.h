/* cutproxy.h - a loopback TCP proxy for libsdfclient's re-send tests: it stands for a
 * load balancer in front of a replica that dies, drains, or is going away. Connection i
 * (counting from 0) follows plan[i] (the last entry for the rest): it relays both ways, and
 * once it has relayed `reply_bytes` bytes from the server (or the client has sent
 * `request_bytes`), it closes both ends, with a reset instead of a FIN when `reset` is set.
 * A negative limit never cuts. With `accept_reset` it resets the connection as soon as it
 * accepts it (a balancer whose replica went away). With `unavailable` it answers the first
 * QUERY or VOLUME_QUERY itself with the ERROR a draining sdfd sends (503 EUNAVAILABLE,
 * between two of the server's reply frames) and relays everything else; its limits are
 * ignored. Connections are served one after another, which is how one client handle uses
 * them. */
#ifndef SDF_TESTS_CUTPROXY_H
#define SDF_TESTS_CUTPROXY_H

#include <pthread.h>

typedef struct cut_plan {
    long reply_bytes;   /* < 0: no limit */
    long request_bytes; /* < 0: no limit */
    int reset;
    int accept_reset;
    int unavailable;
} cut_plan;

typedef struct cut_proxy {
    int listen_fd, port, upstream_port;
    const cut_plan *plan;
    int nplan;
    _Atomic int connections; /* accepted so far */
    _Atomic int stop;
    pthread_t thread;
} cut_proxy;

/* Start a proxy on a free loopback port to 127.0.0.1:upstream_port; 0 or -1. `plan` must
 * outlive the proxy. */
int cut_proxy_start(cut_proxy *p, int upstream_port, const cut_plan *plan, int nplan);
/* Stop it (within 100 ms) and close what it holds. */
void cut_proxy_stop(cut_proxy *p);

#endif
