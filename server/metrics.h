/* metrics.h - counters and histograms for /metrics (Prometheus text format 0.0.4). All
 * updates are lock-free atomics so recording costs nothing measurable on the hot path. */
#ifndef SDFD_METRICS_H
#define SDFD_METRICS_H

#include <stddef.h>

typedef struct sdfd_metrics sdfd_metrics;

/* Routes the request counter distinguishes. */
typedef enum sdfd_route {
    SDFD_ROUTE_HEALTH, SDFD_ROUTE_READY, SDFD_ROUTE_METRICS, SDFD_ROUTE_MESHES,
    SDFD_ROUTE_MESH, SDFD_ROUTE_QUERY, SDFD_ROUTE_BAKE, SDFD_ROUTE_JOBS, SDFD_ROUTE_JOB,
    SDFD_ROUTE_VOLUMES, SDFD_ROUTE_VOLUME, SDFD_ROUTE_VOLUME_DATA, SDFD_ROUTE_VOLUME_QUERY,
    SDFD_ROUTE_BIN_QUERY, SDFD_ROUTE_BIN_VOLUME_QUERY, SDFD_ROUTE_BIN_OTHER, SDFD_ROUTE_OTHER,
    SDFD_ROUTE_SLICE, SDFD_ROUTE_VOLUME_SLICE, SDFD_ROUTE_PAGE, SDFD_ROUTE_VOLUME_OPS,
    SDFD_ROUTE_COUNT
} sdfd_route;

/* The route's label in /metrics and the logs, e.g. "/v1/meshes/{name}/query". */
const char *sdfd_route_name(sdfd_route route);

sdfd_metrics *sdfd_metrics_create(void);
void sdfd_metrics_destroy(sdfd_metrics *m);

void sdfd_metrics_request(sdfd_metrics *m, sdfd_route route, int status, double seconds);
void sdfd_metrics_points(sdfd_metrics *m, size_t points);
void sdfd_metrics_batch(sdfd_metrics *m, size_t requests, size_t points, double seconds);
void sdfd_metrics_queue_depth(sdfd_metrics *m, long delta);
void sdfd_metrics_store_load(sdfd_metrics *m, double seconds);

/* Gauges owned elsewhere, read when /metrics is rendered. */
typedef struct sdfd_gauges {
    size_t meshes_loaded, volumes_loaded, volume_bytes, bakes_running, bakes_queued;
    size_t ops_running, ops_queued; /* field-operation jobs */
    size_t buffered_bytes; /* request bodies and binary input held (--max-buffered-bytes) */
    size_t batch_scratch_bytes; /* what the batcher keeps between batches */
    size_t workers_idle, workers_started; /* worker threads waiting; started since start */
    size_t resident_bytes, resident_budget; /* meshes and volumes in memory; the budget */
    unsigned long long store_loads, store_evictions, store_quarantined;
} sdfd_gauges;

/* Render everything (plus the given gauges) into a new string. */
char *sdfd_metrics_render(sdfd_metrics *m, const sdfd_gauges *g, size_t *len);

#endif
