/* metrics.c - Prometheus counters and histograms (see metrics.h). Statuses are kept per
 * route in a fixed table of the codes sdfd answers with. */
#include "core/metrics.h"

#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const int statuses[] = {200, 201, 202, 204, 400, 401, 404, 405, 411, 413, 415, 422, 429, 500, 503};
#define N_STATUS (sizeof statuses / sizeof statuses[0])
/* A histogram with fixed upper bounds (+Inf implied). */
#define MAX_BUCKETS 16
typedef struct histogram {
    const char *name, *help;
    const double *bounds;
    int n;
    atomic_ullong buckets[MAX_BUCKETS + 1];
    atomic_ullong count;
    _Atomic double sum;
} histogram;

static const double latency_bounds[] = {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01,
                                        0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10};
static const double request_bounds[] = {1, 2, 4, 8, 16, 32, 64, 128, 256};
static const double point_bounds[] = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000};

struct sdfd_metrics {
    const char *labels[SDFD_METRICS_MAX_LABELS];
    size_t n_labels;
    atomic_ullong requests[SDFD_METRICS_MAX_LABELS][N_STATUS + 1];
    atomic_ullong points;
    atomic_long queue_depth;
    histogram latency, batch_requests, batch_points, batch_seconds, store_load_seconds;
};

static void hist_init(histogram *h, const char *name, const char *help, const double *b, int n)
{
    memset(h, 0, sizeof *h);
    h->name = name, h->help = help, h->bounds = b, h->n = n;
}

static void hist_observe(histogram *h, double v)
{
    int i = 0;
    while (i < h->n && v > h->bounds[i])
        i++;
    atomic_fetch_add(&h->buckets[i], 1);
    atomic_fetch_add(&h->count, 1);
    double old = atomic_load(&h->sum);
    while (!atomic_compare_exchange_weak(&h->sum, &old, old + v))
        ;
}

sdfd_metrics *sdfd_metrics_create(const char *const *labels, size_t n)
{
    sdfd_metrics *m = n <= SDFD_METRICS_MAX_LABELS ? calloc(1, sizeof *m) : NULL;
    if (!m)
        return NULL;
    if (n)
        memcpy(m->labels, labels, n * sizeof *labels);
    m->n_labels = n;
    hist_init(&m->latency, "sdfd_request_seconds", "Request latency, receipt to reply.",
              latency_bounds, 16);
    hist_init(&m->batch_requests, "sdfd_batch_requests", "Requests coalesced into one batch.",
              request_bounds, 9);
    hist_init(&m->batch_points, "sdfd_batch_points", "Points in one batch.", point_bounds, 8);
    hist_init(&m->batch_seconds, "sdfd_batch_seconds", "Time to compute one batch.",
              latency_bounds, 16);
    hist_init(&m->store_load_seconds, "sdfd_store_load_seconds",
              "Time to load one mesh or volume from the store (read, check, parse, index).",
              latency_bounds, 16);
    return m;
}

void sdfd_metrics_destroy(sdfd_metrics *m) { free(m); }

void sdfd_metrics_request(sdfd_metrics *m, size_t label, int status, double seconds)
{
    size_t s = 0;
    while (s < N_STATUS && statuses[s] != status)
        s++;
    if (label < m->n_labels)
        atomic_fetch_add(&m->requests[label][s], 1);
    hist_observe(&m->latency, seconds);
}

void sdfd_metrics_points(sdfd_metrics *m, size_t points) { atomic_fetch_add(&m->points, points); }

void sdfd_metrics_batch(sdfd_metrics *m, size_t requests, size_t points, double seconds)
{
    hist_observe(&m->batch_requests, (double)requests);
    hist_observe(&m->batch_points, (double)points);
    hist_observe(&m->batch_seconds, seconds);
}

void sdfd_metrics_store_load(sdfd_metrics *m, double seconds)
{
    hist_observe(&m->store_load_seconds, seconds);
}

void sdfd_metrics_queue_depth(sdfd_metrics *m, long delta) { atomic_fetch_add(&m->queue_depth, delta); }

typedef struct out {
    char *s;
    size_t len, cap;
} out;

static void emit(out *o, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void emit(out *o, const char *fmt, ...)
{
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(o->s ? o->s + o->len : NULL, o->s ? o->cap - o->len : 0, fmt, ap);
        va_end(ap);
        if (n < 0)
            return;
        if (o->s && o->len + (size_t)n < o->cap) {
            o->len += (size_t)n;
            return;
        }
        size_t cap = (o->cap + (size_t)n + 1) * 2;
        char *s = realloc(o->s, cap);
        if (!s)
            return;
        o->s = s, o->cap = cap;
    }
}

static void render_histogram(out *o, histogram *h)
{
    emit(o, "# HELP %s %s\n# TYPE %s histogram\n", h->name, h->help, h->name);
    unsigned long long cumulative = 0;
    for (int i = 0; i <= h->n; i++) {
        cumulative += atomic_load(&h->buckets[i]);
        if (i < h->n)
            emit(o, "%s_bucket{le=\"%g\"} %llu\n", h->name, h->bounds[i], cumulative);
        else
            emit(o, "%s_bucket{le=\"+Inf\"} %llu\n", h->name, cumulative);
    }
    emit(o, "%s_sum %.9g\n%s_count %llu\n", h->name, atomic_load(&h->sum), h->name,
         (unsigned long long)atomic_load(&h->count));
}

/* Whether index r is the first with its label text (which reports the label's series). */
static int first_of_label(const sdfd_metrics *m, size_t r)
{
    for (size_t i = 0; i < r; i++)
        if (m->labels[i] && !strcmp(m->labels[i], m->labels[r]))
            return 0;
    return 1;
}

/* The series of label index r, summed over every index with the same label text. */
static void render_requests(out *o, sdfd_metrics *m, size_t r)
{
    for (size_t s = 0; s <= N_STATUS; s++) {
        unsigned long long v = 0;
        for (size_t i = r; i < m->n_labels; i++)
            if (m->labels[i] && !strcmp(m->labels[i], m->labels[r]))
                v += atomic_load(&m->requests[i][s]);
        char status[16];
        if (s < N_STATUS)
            snprintf(status, sizeof status, "%d", statuses[s]);
        else
            snprintf(status, sizeof status, "other");
        if (v)
            emit(o, "sdfd_requests_total{route=\"%s\",status=\"%s\"} %llu\n", m->labels[r],
                 status, v);
    }
}

char *sdfd_metrics_render(sdfd_metrics *m, const sdfd_gauges *g, size_t *len)
{
    out o = {0};
    emit(&o, "# HELP sdfd_requests_total Requests answered, by route and status.\n"
             "# TYPE sdfd_requests_total counter\n");
    for (size_t r = 0; r < m->n_labels; r++)
        if (m->labels[r] && first_of_label(m, r))
            render_requests(&o, m, r);
    emit(&o, "# HELP sdfd_points_total Points queried.\n# TYPE sdfd_points_total counter\n"
             "sdfd_points_total %llu\n", (unsigned long long)atomic_load(&m->points));
    emit(&o, "# HELP sdfd_queue_depth Requests waiting for the batcher.\n"
             "# TYPE sdfd_queue_depth gauge\nsdfd_queue_depth %ld\n", atomic_load(&m->queue_depth));
    emit(&o, "# HELP sdfd_meshes_loaded Meshes being served.\n# TYPE sdfd_meshes_loaded gauge\n"
             "sdfd_meshes_loaded %zu\n", g->meshes_loaded);
    emit(&o, "# HELP sdfd_volumes_loaded Baked volumes being served.\n"
             "# TYPE sdfd_volumes_loaded gauge\nsdfd_volumes_loaded %zu\n", g->volumes_loaded);
    emit(&o, "# HELP sdfd_volume_bytes Bytes of the baked volumes.\n"
             "# TYPE sdfd_volume_bytes gauge\nsdfd_volume_bytes %zu\n", g->volume_bytes);
    emit(&o, "# HELP sdfd_buffered_bytes Bytes of request bodies and binary input held.\n"
             "# TYPE sdfd_buffered_bytes gauge\nsdfd_buffered_bytes %zu\n", g->buffered_bytes);
    emit(&o, "# HELP sdfd_batch_scratch_bytes Bytes the batcher keeps between batches.\n"
             "# TYPE sdfd_batch_scratch_bytes gauge\nsdfd_batch_scratch_bytes %zu\n",
         g->batch_scratch_bytes);
    emit(&o, "# HELP sdfd_worker_threads_idle Worker threads waiting for a task.\n"
             "# TYPE sdfd_worker_threads_idle gauge\nsdfd_worker_threads_idle %zu\n",
         g->workers_idle);
    emit(&o, "# HELP sdfd_worker_threads_started_total Worker threads started (for uploads, "
             "slices, volume queries).\n# TYPE sdfd_worker_threads_started_total counter\n"
             "sdfd_worker_threads_started_total %zu\n", g->workers_started);
    emit(&o, "# HELP sdfd_bakes Bake jobs by state.\n# TYPE sdfd_bakes gauge\n"
             "sdfd_bakes{state=\"running\"} %zu\nsdfd_bakes{state=\"queued\"} %zu\n",
         g->bakes_running, g->bakes_queued);
    emit(&o, "# HELP sdfd_ops_jobs Field-operation jobs by state.\n# TYPE sdfd_ops_jobs gauge\n"
             "sdfd_ops_jobs{state=\"running\"} %zu\nsdfd_ops_jobs{state=\"queued\"} %zu\n",
         g->ops_running, g->ops_queued);
    emit(&o, "# HELP sdfd_resident_bytes Bytes of the meshes and volumes in memory.\n"
             "# TYPE sdfd_resident_bytes gauge\nsdfd_resident_bytes %zu\n", g->resident_bytes);
    emit(&o, "# HELP sdfd_resident_budget_bytes --max-resident-bytes (0: none).\n"
             "# TYPE sdfd_resident_budget_bytes gauge\nsdfd_resident_budget_bytes %zu\n",
         g->resident_budget);
    emit(&o, "# HELP sdfd_store_loads_total Meshes and volumes loaded from the store.\n"
             "# TYPE sdfd_store_loads_total counter\nsdfd_store_loads_total %llu\n", g->store_loads);
    emit(&o, "# HELP sdfd_store_evictions_total Meshes and volumes dropped from memory.\n"
             "# TYPE sdfd_store_evictions_total counter\nsdfd_store_evictions_total %llu\n",
         g->store_evictions);
    emit(&o, "# HELP sdfd_store_quarantined_total Store items moved to quarantine on use.\n"
             "# TYPE sdfd_store_quarantined_total counter\nsdfd_store_quarantined_total %llu\n",
         g->store_quarantined);
    render_histogram(&o, &m->latency);
    render_histogram(&o, &m->batch_requests);
    render_histogram(&o, &m->batch_points);
    render_histogram(&o, &m->batch_seconds);
    render_histogram(&o, &m->store_load_seconds);
    emit(&o, "# HELP sdfd_store_hits_total Lookups of stored items answered from memory "
             "(the misses are sdfd_store_loads_total).\n"
             "# TYPE sdfd_store_hits_total counter\nsdfd_store_hits_total %llu\n", g->store_hits);
    if (g->extra)
        emit(&o, "%.*s", (int)g->extra_len, g->extra);
    *len = o.len;
    return o.s;
}
