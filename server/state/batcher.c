/* batcher.c - coalescing dispatcher (see batcher.h). */
#include "state/batcher.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/errors.h"
#include "core/log.h"

struct sdfd_batcher {
    pthread_mutex_t lock;
    pthread_cond_t wake;
    pthread_t thread;
    sdfd_job *head, *tail;   /* FIFO */
    int stopping;
    int threads;
    double window;
    size_t max_points;
    size_t max_queued, queued; /* points waiting */
    sdfd_metrics *metrics;
    /* scratch for the dispatcher thread only, grown as needed */
    float *points, *distance, *vec3;
    uint32_t *triangle;
    size_t capacity;
    size_t scratch_bytes; /* what those four arrays hold (ensure_scratch) */
    /* the library's scratch, kept between batches of up to max_points (query_batch) */
    sdf_workspace *workspace;
    _Atomic size_t kept_bytes; /* the two kept, for /metrics: set between batches */
};

double sdfd_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* ---- the batch key ------------------------------------------------------------------------
 * Jobs share a batch only when their keys are equal byte for byte. A key holds the mesh, the
 * mode, the sign and, for the filtered modes, every scalar of sdf_filter_options, so no
 * parameter can be left out of the comparison by accident: FILTER_SCALARS names them all,
 * and two guards below fail the build when the library's structs gain a field it does not
 * name. Two spellings of one answer are made one: any nonzero sample_gradient is 1, and a
 * smoothing volume of shape NONE has its unused fields zeroed. Floats compare by their bits,
 * which only keeps apart what == would join (0 and -0), never the reverse for a valid
 * request (NaN parameters are refused before submission). */

/* Every scalar of sdf_filter_options in declaration order, arrays element by element; with
 * brace elision the list is also the struct's positional initializer (see check_scalars). */
#define FILTER_SCALARS(X, f, s)                                                             \
    X(f->kernel) X(f->cap) X(f->a) X(f->b) X(f->samples) X(f->min_samples) X(f->medial)     \
    X(f->grid) X(f->unsigned_integrand) X(f->allow_wide_bump) X(!!f->sample_gradient)       \
    X(f->seed) X(s->shape) X(s->center[0]) X(s->center[1]) X(s->center[2]) X(s->radius)     \
    X(s->lo[0]) X(s->lo[1]) X(s->lo[2]) X(s->hi[0]) X(s->hi[1]) X(s->hi[2]) X(s->mesh)      \
    X(s->depth) X(s->scale)

#define KEY_GUARD_ADVICE                                                                    \
    "sdf_filter_options or sdf_smoothing_volume changed: name the new field in "             \
    "FILTER_SCALARS (server/state/batcher.c), so requests that differ in it never share a batch, " \
    "add a case for it to tests/server/test_batcher.c, then update the size checked here"

/* Guard 1: the structs' sizes when FILTER_SCALARS was last brought up to date (LP64). */
_Static_assert(sizeof(void *) != 8 || (sizeof(sdf_smoothing_volume) == 112 &&
                                       sizeof(sdf_filter_options) == 184),
               KEY_GUARD_ADVICE);

/* Guard 2, for a field that fits in padding and leaves the size alone: FILTER_SCALARS as a
 * positional initializer leaves any field it does not name uninitialized, which
 * -Wmissing-field-initializers reports, an error in this function. */
#pragma GCC diagnostic push
#pragma GCC diagnostic error "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wmissing-braces"
#define KEY_INIT(v) v,
static void check_scalars(const sdf_filter_options *f, const sdf_smoothing_volume *s)
{
    sdf_filter_options all = {FILTER_SCALARS(KEY_INIT, f, s)}; /* KEY_GUARD_ADVICE */
    (void)all;
}
#undef KEY_INIT
#pragma GCC diagnostic pop

/* Append the bytes of one value, as its own type, to the key. */
#define KEY_PUT(v)                                                                          \
    do {                                                                                    \
        __typeof__(v) value_ = (v);                                                         \
        memcpy(key->bytes + at, &value_, sizeof value_);                                    \
        at += sizeof value_;                                                                \
    } while (0);
#define KEY_SIZE(v) +sizeof(v)

void sdfd_batch_key_of(const sdfd_job *job, sdfd_batch_key *key)
{
    memset(key, 0, sizeof *key);
    size_t at = 0;
    KEY_PUT(job->mesh) KEY_PUT(job->mode) KEY_PUT(job->sign)
    if (!sdf_proto_mode_filtered(job->mode))
        return; /* the filter is not read */
    static const sdf_smoothing_volume everywhere = {.shape = SDF_VOLUME_NONE};
    const sdf_filter_options *f = &job->filter;
    const sdf_smoothing_volume *s = f->smooth.shape == SDF_VOLUME_NONE ? &everywhere : &f->smooth;
    (void)check_scalars;
    _Static_assert(sizeof(job->mesh) + sizeof(job->mode) + sizeof(job->sign)
                   FILTER_SCALARS(KEY_SIZE, f, s) <= sizeof key->bytes,
                   "the key's bytes hold every scalar");
    FILTER_SCALARS(KEY_PUT, f, s)
}
#undef KEY_PUT
#undef KEY_SIZE

static int same_batch(const sdfd_job *a, const sdfd_job *b)
{
    return !memcmp(&a->key, &b->key, sizeof a->key);
}

int sdfd_filter_validate(const sdf_mesh *mesh, const sdf_filter_options *f, size_t count,
                         size_t max_queries, char *msg, size_t cap)
{
    sdf_query_result none = {0};
    sdf_diag diag = {0};
    int rc = sdf_query_filtered(mesh, NULL, 0, NULL, f, &none, &diag);
    if (rc) {
        snprintf(msg, cap, "%s", diag.message);
        return rc;
    }
    /* n samples, the point itself, and the adaptive stencil's 26. */
    size_t per_point = (size_t)(f->samples ? f->samples : SDF_FILTER_DEFAULT_SAMPLES) + 1 +
                       (f->min_samples ? 26 : 0);
    if (count > max_queries / per_point) {
        snprintf(msg, cap, "%zu points x %zu queries each exceeds the %zu distance queries one "
                 "filtered request may cost; send fewer points or samples", count, per_point,
                 max_queries);
        return SDF_ELIMIT;
    }
    return 0;
}

/* Take the head job and every queued job of the same key (up to max_points); caller holds
 * the lock. Returns the list, linked through next. */
static sdfd_job *take_batch(sdfd_batcher *b, size_t *requests, size_t *points)
{
    sdfd_job *first = b->head, *list = first, *last = first;
    b->head = first->next;
    if (!b->head)
        b->tail = NULL;
    first->next = NULL;
    *requests = 1;
    *points = first->count;
    sdfd_job **link = &b->head, *prev = NULL;
    while (*link && *points < b->max_points) {
        sdfd_job *j = *link;
        if (same_batch(first, j) && *points + j->count <= b->max_points) {
            *link = j->next;
            if (b->tail == j)
                b->tail = prev;
            j->next = NULL;
            last->next = j;
            last = j;
            ++*requests;
            *points += j->count;
        } else {
            prev = j;
            link = &j->next;
        }
    }
    return list;
}

/* Points of the same key waiting, counting from the head (caller holds the lock). */
static size_t waiting_points(const sdfd_batcher *b)
{
    size_t n = 0;
    for (const sdfd_job *j = b->head; j; j = j->next)
        if (same_batch(b->head, j))
            n += j->count;
    return n;
}

static int ensure_scratch(sdfd_batcher *b, size_t n)
{
    if (n <= b->capacity)
        return 0;
    free(b->points), free(b->distance), free(b->vec3), free(b->triangle);
    size_t xyz = 3 * n * sizeof(float), one = n * sizeof(float), ids = n * sizeof(uint32_t);
    b->points = malloc(xyz);
    b->distance = malloc(one);
    b->vec3 = malloc(xyz);
    b->triangle = malloc(ids);
    b->capacity = b->points && b->distance && b->vec3 && b->triangle ? n : 0;
    b->scratch_bytes = b->capacity ? 2 * xyz + one + ids : 0;
    return b->capacity ? 0 : SDF_ENOMEM;
}

/* Write results [offset, offset + count) of the batch into the job in wire layout. */
static void scatter(const sdfd_batcher *b, sdfd_job *j, size_t offset)
{
    unsigned w = sdf_proto_words(j->mode);
    for (size_t i = 0; i < j->count; i++) {
        uint32_t *dst = j->words + (size_t)w * i;
        size_t k = offset + i;
        memcpy(dst, &b->distance[k], 4);
        if (w >= 4)
            memcpy(dst + 1, &b->vec3[3 * k], 12);
        if (w == 5)
            dst[4] = b->triangle[k];
    }
}

_Static_assert(sizeof((sdfd_job *)0)->message >= sizeof((sdf_diag *)0)->message,
               "a job holds the library's whole message");

/* Run the jobs linked from `list` (points in all) as one library call; its results land in
 * the scratch arrays in list order. Returns 0 or an SDF_E* code with `message` set. */
static int query_batch(sdfd_batcher *b, sdfd_job *list, size_t points, char *message,
                       size_t cap)
{
    message[0] = '\0';
    if (ensure_scratch(b, points)) {
        snprintf(message, cap, "out of memory for a batch of %zu points", points);
        return SDF_ENOMEM;
    }
    const float *p = list->points;
    if (list->next) { /* several jobs: gathered into one contiguous batch */
        size_t at = 0;
        for (sdfd_job *j = list; j; j = j->next) {
            memcpy(b->points + 3 * at, j->points, 3 * j->count * sizeof(float));
            at += j->count;
        }
        p = b->points;
    }
    sdf_proto_mode mode = list->mode;
    sdf_query_options opts = {.sign = mode == SDF_MODE_DISTANCE ? SDF_SIGN_NONE : list->sign,
                              .threads = b->threads};
    /* Batches up to the coalescing cap keep the library's scratch between them; a larger
     * request (a batch of its own) allocates its own, so the kept memory stays bounded. */
    if (points <= b->max_points)
        opts.workspace = b->workspace;
    int with_gradient = mode == SDF_MODE_GRADIENT || mode == SDF_MODE_FILTERED_GRADIENT;
    sdf_query_result res = {.distance = b->distance,
                            .gradient = with_gradient ? b->vec3 : NULL,
                            .closest = mode == SDF_MODE_CLOSEST ? b->vec3 : NULL,
                            .triangle = mode == SDF_MODE_CLOSEST ? b->triangle : NULL};
    sdf_diag diag = {0};
    int rc = sdf_proto_mode_filtered(mode) /* parameters were validated at submission */
                 ? sdf_query_filtered(list->mesh, p, points, &opts, &list->filter, &res, &diag)
                 : sdf_query(list->mesh, p, points, &opts, &res);
    if (rc)
        snprintf(message, cap, "%s", diag.message[0] ? diag.message : sdfd_strerror(rc));
    return rc;
}

static size_t kept_bytes(const sdfd_batcher *b);

/* Answer the jobs of one query_batch call and hand each to its `done`. The kept bytes are
 * published first: a client that reads /metrics after its answer sees its batch's. */
static void deliver(sdfd_batcher *b, sdfd_job *list, int rc, const char *message)
{
    atomic_store(&b->kept_bytes, kept_bytes(b));
    size_t offset = 0;
    for (sdfd_job *j = list, *next; j; j = next) {
        next = j->next; /* done() may free the job */
        j->status = rc;
        snprintf(j->message, sizeof j->message, "%s", rc ? message : "");
        if (!rc)
            scatter(b, j, offset);
        offset += j->count;
        sdfd_metrics_queue_depth(b->metrics, -1);
        j->done(j);
    }
}

/* The scratch arrays' bytes (points, distance, vec3, triangle) and the workspace's. */
static size_t kept_bytes(const sdfd_batcher *b)
{
    return b->scratch_bytes + sdf_workspace_bytes(b->workspace);
}

static void run_batch(sdfd_batcher *b, sdfd_job *list, size_t requests, size_t points)
{
    double start = sdfd_now();
    char message[sizeof list->message];
    int rc = query_batch(b, list, points, message, sizeof message);
    sdfd_metrics_batch(b->metrics, requests, points, sdfd_now() - start);
    if (rc && requests > 1) {
        /* One request's points or the batch's size failed them all: each on its own, so
         * only the one that cannot be answered hears of it. */
        for (sdfd_job *j = list, *next; j; j = next) {
            next = j->next;
            j->next = NULL;
            rc = query_batch(b, j, j->count, message, sizeof message);
            deliver(b, j, rc, message);
        }
    } else {
        deliver(b, list, rc, message);
    }
}

static void wait_until(sdfd_batcher *b, double deadline)
{
    double left = deadline - sdfd_now();
    if (left <= 0)
        return;
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    double whole, frac = modf(left, &whole);
    ts.tv_sec += (time_t)whole;
    ts.tv_nsec += (long)(frac * 1e9);
    if (ts.tv_nsec >= 1000000000L)
        ts.tv_sec++, ts.tv_nsec -= 1000000000L;
    pthread_cond_timedwait(&b->wake, &b->lock, &ts);
}

static void *dispatcher(void *arg)
{
    sdfd_batcher *b = arg;
    pthread_mutex_lock(&b->lock);
    for (;;) {
        while (!b->head && !b->stopping)
            pthread_cond_wait(&b->wake, &b->lock);
        if (!b->head)
            break; /* stopping, and nothing left */
        /* Give other requests for the same batch a moment to arrive. */
        double deadline = b->head->enqueued + b->window;
        while (!b->stopping && sdfd_now() < deadline && waiting_points(b) < b->max_points)
            wait_until(b, deadline);
        size_t requests, points;
        sdfd_job *list = take_batch(b, &requests, &points);
        b->queued -= points;
        pthread_mutex_unlock(&b->lock);
        run_batch(b, list, requests, points);
        pthread_mutex_lock(&b->lock);
    }
    pthread_mutex_unlock(&b->lock);
    return NULL;
}

int sdfd_batcher_create(int threads, unsigned window_us, size_t max_points, size_t max_queued,
                        sdfd_metrics *metrics, sdfd_batcher **out)
{
    sdfd_batcher *b = calloc(1, sizeof *b);
    if (!b)
        return SDF_ENOMEM;
    pthread_mutex_init(&b->lock, NULL);
    pthread_cond_init(&b->wake, NULL);
    b->threads = threads;
    b->window = window_us * 1e-6;
    b->max_points = max_points ? max_points : 1;
    b->max_queued = max_queued;
    b->metrics = metrics;
    if (sdf_workspace_create(&b->workspace) || pthread_create(&b->thread, NULL, dispatcher, b)) {
        sdf_workspace_destroy(b->workspace);
        free(b);
        return SDF_ENOMEM;
    }
    *out = b;
    return 0;
}

void sdfd_batcher_destroy(sdfd_batcher *b)
{
    if (!b)
        return;
    pthread_mutex_lock(&b->lock);
    b->stopping = 1;
    pthread_cond_signal(&b->wake);
    pthread_mutex_unlock(&b->lock);
    pthread_join(b->thread, NULL);
    pthread_cond_destroy(&b->wake);
    pthread_mutex_destroy(&b->lock);
    free(b->points), free(b->distance), free(b->vec3), free(b->triangle);
    sdf_workspace_destroy(b->workspace);
    free(b);
}

size_t sdfd_batcher_kept_bytes(sdfd_batcher *b)
{
    return atomic_load(&b->kept_bytes);
}

int sdfd_batcher_submit(sdfd_batcher *b, sdfd_job *job, size_t *bad_index)
{
    /* The library's own check, made here so that one request's bad point cannot fail a
     * batch it shares with others (NaN fails the comparison too). */
    for (size_t i = 0; i < 3 * job->count; i++) {
        if (!(fabsf(job->points[i]) <= SDF_MAX_COORDINATE)) {
            if (bad_index)
                *bad_index = i / 3;
            return SDF_ENONFINITE;
        }
    }
    sdfd_batch_key_of(job, &job->key);
    job->next = NULL;
    job->enqueued = sdfd_now();
    pthread_mutex_lock(&b->lock);
    if (b->stopping) {
        pthread_mutex_unlock(&b->lock);
        return SDFD_EUNAVAILABLE;
    }
    if (b->head && b->queued + job->count > b->max_queued) { /* an idle queue takes any job */
        pthread_mutex_unlock(&b->lock);
        return SDFD_EBUSY;
    }
    b->queued += job->count;
    if (b->tail)
        b->tail->next = job;
    else
        b->head = job;
    b->tail = job;
    sdfd_metrics_queue_depth(b->metrics, 1);
    pthread_cond_signal(&b->wake);
    pthread_mutex_unlock(&b->lock);
    return 0;
}
