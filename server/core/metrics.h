/* metrics.h - counters and histograms for /metrics (Prometheus text format 0.0.4). All
 * updates are lock-free atomics so recording costs nothing measurable on the hot path. */
#ifndef SDFD_METRICS_H
#define SDFD_METRICS_H

#include <stddef.h>

typedef struct sdfd_metrics sdfd_metrics;

/* The request counter is kept per label index, 0..n-1, of the labels given at creation
 * (at most SDFD_METRICS_MAX_LABELS; NULL entries unused). Indices that share a label text
 * are reported as one series: "/v1/meshes/{name}" counts its GET, PUT and DELETE. */
#define SDFD_METRICS_MAX_LABELS 64
sdfd_metrics *sdfd_metrics_create(const char *const *labels, size_t n);
void sdfd_metrics_destroy(sdfd_metrics *m);

void sdfd_metrics_request(sdfd_metrics *m, size_t label, int status, double seconds);
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
    unsigned long long store_hits; /* lookups answered from memory */
    const char *extra;             /* more series, in the text format, appended; or NULL */
    size_t extra_len;
} sdfd_gauges;

/* Render everything (plus the given gauges) into a new string. */
char *sdfd_metrics_render(sdfd_metrics *m, const sdfd_gauges *g, size_t *len);

#endif
