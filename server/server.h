/* server.h - the state every part of sdfd shares: settings, the mesh registry, metrics,
 * the batcher, and the lifecycle flags that drive /readyz and graceful shutdown. */
#ifndef SDFD_SERVER_H
#define SDFD_SERVER_H

#include <stdatomic.h>

#include "batcher.h"
#include "config.h"
#include "metrics.h"
#include "registry.h"
#include "volumes.h"

#define SDFD_VERSION "0.1.0"

typedef struct sdfd_server {
    sdfd_config cfg;
    sdfd_registry *registry;
    sdfd_metrics *metrics;
    sdfd_batcher *batcher;
    sdfd_volumes *volumes;   /* baked volumes and bake jobs */
    atomic_int ready;        /* meshes loaded: /readyz 200 */
    atomic_int draining;     /* SIGTERM seen: /readyz 503, new work refused */
    atomic_long in_flight;   /* requests received and not yet answered (both protocols) */
} sdfd_server;

/* Open a listening TCP socket on "HOST:PORT"; returns the fd (and the bound port in *port)
 * or -1 after logging why. */
int sdfd_listen(const char *addr, int *port);

#endif
