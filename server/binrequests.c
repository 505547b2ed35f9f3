/* binrequests.c - what the binary front end answers (PROTOCOL.md): QUERY becomes a batcher
 * job whose reply frame is built in place (the result words sit right after the frame
 * header, so nothing is copied) and queued by the dispatcher thread; VOLUME_QUERY runs on a
 * thread of its own; HELLO, LIST_MESHES and AUTH are answered at once on the poll thread.
 * The connections themselves (polling, framing, limits) are binary.c's. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "binconn.h"
#include "errors.h"
#include "log.h"

/* ---- queries ----------------------------------------------------------------------------- */

typedef struct bin_job {
    sdfd_job job;
    connection *conn;
    uint32_t request_id;
    char *frame;  /* header + result prefix + words */
    float *points;
    sdf_mesh *volume; /* a filtered query's smoothing mesh, held until the reply */
    double start;
    size_t bytes_in;
} bin_job;

static void query_done(sdfd_job *job)
{
    bin_job *bj = (bin_job *)job;
    connection *c = bj->conn;
    sdfd_binary *b = job->user;
    int status = job->status ? sdfd_http_status(job->status) : 200;
    size_t len = SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX +
                 4 * sdf_proto_words(job->mode) * job->count;
    if (job->status) {
        sdfd_bin_send_error(c, bj->request_id, job->status, job->message);
        free(bj->frame);
    } else {
        sdfd_bin_enqueue(c, bj->frame, len);
    }
    sdfd_bin_account(b, SDFD_ROUTE_BIN_QUERY, "QUERY", status, job->count, bj->start,
                     bj->bytes_in, job->status ? 0 : len);
    sdf_mesh_release(job->mesh);
    sdf_mesh_release(bj->volume);
    free(bj->points);
    free(bj);
    sdfd_bin_request_finished(b, c);
    sdfd_bin_wake(b);
}

/* Refuse a query: ERROR frame, metrics, log. */
static void refuse(sdfd_binary *b, connection *c, uint32_t id, int err, const char *message,
                   double start, size_t bytes_in)
{
    sdfd_bin_send_error(c, id, err, message);
    sdfd_bin_account(b, SDFD_ROUTE_BIN_QUERY, "QUERY", sdfd_http_status(err), 0, start, bytes_in, 0);
}

static void handle_query(sdfd_binary *b, connection *c, uint32_t id, const unsigned char *payload,
                         size_t len)
{
    sdfd_server *srv = b->srv;
    double start = sdfd_now();
    size_t bytes_in = SDF_PROTO_HEADER_SIZE + len;
    sdf_proto_query q;
    const char *why;
    int rc = sdf_proto_decode_query(payload, len, (uint32_t)srv->cfg.max_points, &q, &why);
    if (rc) {
        refuse(b, c, id, rc, why, start, bytes_in);
        return;
    }
    if (atomic_load(&srv->draining)) {
        refuse(b, c, id, SDFD_EUNAVAILABLE, "the server is shutting down", start, bytes_in);
        return;
    }
    sdf_mesh *mesh = sdfd_registry_get(srv->registry, q.name, q.name_len);
    if (!mesh) {
        char message[300];
        snprintf(message, sizeof message, "no mesh named '%.*s'", (int)q.name_len, q.name);
        refuse(b, c, id, SDF_ENOTFOUND, message, start, bytes_in);
        return;
    }
    sdf_mesh *volume = NULL;
    if (sdf_proto_mode_filtered(q.mode)) {
        char message[300];
        if (q.volume_name) {
            volume = sdfd_registry_get(srv->registry, q.volume_name, q.volume_name_len);
            if (!volume) {
                snprintf(message, sizeof message, "no smoothing mesh named '%.*s'",
                         (int)q.volume_name_len, q.volume_name);
                sdf_mesh_release(mesh);
                refuse(b, c, id, SDF_ENOTFOUND, message, start, bytes_in);
                return;
            }
            q.filter.smooth.mesh = volume;
        }
        int bad = sdfd_filter_validate(mesh, &q.filter, q.count,
                                       SDFD_FILTER_QUERIES_PER_POINT_LIMIT * srv->cfg.max_points,
                                       message, sizeof message);
        if (bad) {
            sdf_mesh_release(mesh);
            sdf_mesh_release(volume);
            refuse(b, c, id, bad, message, start, bytes_in);
            return;
        }
    }
    bin_job *bj = calloc(1, sizeof *bj);
    size_t words = (size_t)sdf_proto_words(q.mode) * q.count;
    if (bj) {
        bj->frame = malloc(SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX + 4 * words);
        bj->points = malloc(12 * (size_t)q.count + 4);
    }
    if (!bj || !bj->frame || !bj->points) {
        if (bj)
            free(bj->frame), free(bj->points);
        free(bj);
        sdf_mesh_release(mesh);
        sdf_mesh_release(volume);
        refuse(b, c, id, SDF_ENOMEM, "out of memory", start, bytes_in);
        return;
    }
    memcpy(bj->points, q.points, 12 * (size_t)q.count); /* the input buffer will move on */
    size_t head = sdf_proto_encode_result_head(bj->frame, id, q.mode, q.count);
    bj->conn = c;
    bj->volume = volume;
    bj->request_id = id;
    bj->start = start;
    bj->bytes_in = bytes_in;
    bj->job = (sdfd_job){.mesh = mesh, .mode = q.mode, .sign = q.sign, .filter = q.filter,
                         .points = bj->points,
                         .count = q.count, .words = (uint32_t *)(bj->frame + head),
                         .done = query_done, .user = b};
    pthread_mutex_lock(&c->lock);
    c->in_flight++;
    pthread_mutex_unlock(&c->lock);
    atomic_fetch_add(&srv->in_flight, 1);
    size_t bad = 0;
    rc = sdfd_batcher_submit(srv->batcher, &bj->job, &bad);
    if (rc) {
        char message[96];
        if (rc == SDF_ENONFINITE)
            snprintf(message, sizeof message, SDFD_BAD_POINT_MESSAGE, bad);
        else if (rc == SDFD_EBUSY)
            snprintf(message, sizeof message, "more than %zu points are waiting; retry later",
                     srv->cfg.max_queued_points);
        else
            snprintf(message, sizeof message, "%s", sdfd_strerror(rc));
        refuse(b, c, id, rc, message, start, bytes_in);
        sdf_mesh_release(mesh);
        sdf_mesh_release(volume);
        free(bj->frame), free(bj->points), free(bj);
        sdfd_bin_request_finished(b, c);
        return;
    }
    sdfd_metrics_points(srv->metrics, q.count);
}

/* ---- volume queries: evaluated on a thread of their own (not geometry for the batcher, but
 * too slow for the poll loop), answered like queries ------------------------------------- */

typedef struct volume_job {
    sdfd_binary *b;
    connection *conn;
    uint32_t request_id;
    sdfd_stored_volume *stored;
    sdf_volume_filter interpolation;
    int gradient;
    uint32_t count;
    float *points;
    char *frame;
    double start;
    size_t bytes_in;
} volume_job;

static void *run_volume_query(void *arg)
{
    volume_job *vj = arg;
    connection *c = vj->conn;
    sdfd_binary *b = vj->b;
    size_t head = SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX, bad = 0;
    size_t len = head + 4 * (vj->gradient ? 4 : 1) * (size_t)vj->count;
    int rc = sdfd_volume_eval_words(vj->stored->volume, vj->points, vj->count, vj->interpolation,
                                    vj->gradient, (uint32_t *)(vj->frame + head), &bad);
    if (rc) {
        char message[96];
        if (rc == SDF_ENONFINITE)
            snprintf(message, sizeof message, "point %zu has a NaN or infinite coordinate", bad);
        else
            snprintf(message, sizeof message, "%s", sdfd_strerror(rc));
        sdfd_bin_send_error(c, vj->request_id, rc, message);
        free(vj->frame);
    } else {
        sdfd_bin_enqueue(c, vj->frame, len);
    }
    sdfd_bin_account(b, SDFD_ROUTE_BIN_VOLUME_QUERY, "VOLUME_QUERY",
                     rc ? sdfd_http_status(rc) : 200, vj->count, vj->start, vj->bytes_in,
                     rc ? 0 : len);
    sdfd_volume_release(vj->stored);
    free(vj->points);
    free(vj);
    sdfd_bin_request_finished(b, c);
    sdfd_bin_wake(b);
    return NULL;
}

static void handle_volume_query(sdfd_binary *b, connection *c, uint32_t id,
                                const unsigned char *payload, size_t len)
{
    sdfd_server *srv = b->srv;
    double start = sdfd_now();
    size_t bytes_in = SDF_PROTO_HEADER_SIZE + len;
    sdf_proto_volume_query q;
    const char *why;
    char message[300];
    int rc = sdf_proto_decode_volume_query(payload, len, (uint32_t)srv->cfg.max_points, &q, &why);
    if (rc || atomic_load(&srv->draining)) {
        sdfd_bin_send_error(c, id, rc ? rc : SDFD_EUNAVAILABLE,
                            rc ? why : "the server is shutting down");
        sdfd_bin_account(b, SDFD_ROUTE_BIN_VOLUME_QUERY, "VOLUME_QUERY",
                         sdfd_http_status(rc ? rc : SDFD_EUNAVAILABLE), 0, start, bytes_in, 0);
        return;
    }
    snprintf(message, sizeof message, "%.*s", (int)q.name_len, q.name);
    volume_job *vj = calloc(1, sizeof *vj);
    if (vj && !(vj->stored = sdfd_volumes_get(srv->volumes, message))) {
        free(vj);
        snprintf(message, sizeof message, "no volume named '%.*s'", (int)q.name_len, q.name);
        sdfd_bin_send_error(c, id, SDF_ENOTFOUND, message);
        sdfd_bin_account(b, SDFD_ROUTE_BIN_VOLUME_QUERY, "VOLUME_QUERY", 404, 0, start, bytes_in,
                         0);
        return;
    }
    if (vj) {
        vj->frame = malloc(SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX +
                           4 * (q.gradient ? 4 : 1) * (size_t)q.count);
        vj->points = malloc(12 * (size_t)q.count + 4);
    }
    pthread_t thread;
    pthread_attr_t attr;
    pthread_attr_init(&attr);
    pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
    rc = vj && vj->frame && vj->points ? 0 : SDF_ENOMEM;
    if (!rc) {
        memcpy(vj->points, q.points, 12 * (size_t)q.count); /* the input buffer moves on */
        sdf_proto_encode_result_head(vj->frame, id, q.gradient ? SDF_MODE_GRADIENT : SDF_MODE_SIGNED,
                                     q.count);
        *vj = (volume_job){b, c, id, vj->stored, q.interpolation, q.gradient, q.count, vj->points,
                           vj->frame, start, bytes_in};
        pthread_mutex_lock(&c->lock);
        c->in_flight++;
        pthread_mutex_unlock(&c->lock);
        atomic_fetch_add(&srv->in_flight, 1);
        if (pthread_create(&thread, &attr, run_volume_query, vj)) {
            rc = SDFD_EUNAVAILABLE;
            sdfd_bin_request_finished(b, c);
        }
    }
    pthread_attr_destroy(&attr);
    if (rc) {
        if (vj) {
            sdfd_volume_release(vj->stored);
            free(vj->frame), free(vj->points), free(vj);
        }
        sdfd_bin_send_error(c, id, rc,
                            rc == SDF_ENOMEM ? "out of memory" : "cannot start a worker thread");
        sdfd_bin_account(b, SDFD_ROUTE_BIN_VOLUME_QUERY, "VOLUME_QUERY", sdfd_http_status(rc), 0,
                         start, bytes_in, 0);
        return;
    }
    sdfd_metrics_points(srv->metrics, q.count);
}

static void handle_list(sdfd_binary *b, connection *c, uint32_t id)
{
    sdfd_entry *list;
    size_t n = sdfd_registry_list(b->srv->registry, &list);
    sdf_proto_mesh_entry *entries = calloc(n + 1, sizeof *entries);
    for (size_t i = 0; entries && i < n; i++) {
        sdf_mesh_report r;
        sdf_mesh_get_report(list[i].mesh, &r);
        entries[i] = (sdf_proto_mesh_entry){list[i].name, strlen(list[i].name), r.triangles,
                                            (uint8_t)r.closed, (uint8_t)r.auto_sign};
    }
    size_t size = entries ? sdf_proto_meshes_size(entries, n) : 0;
    char *frame = size ? malloc(size) : NULL;
    if (frame && sdf_proto_encode_meshes(frame, size, id, entries, n) == size)
        sdfd_bin_enqueue(c, frame, size);
    else {
        free(frame);
        sdfd_bin_send_error(c, id, SDF_ENOMEM, "out of memory");
    }
    free(entries);
    sdfd_registry_free_list(list, n);
}

/* AUTH: the payload is the token. A wrong one closes the connection, so guesses cost a
 * connection each. */
static void handle_auth(sdfd_binary *b, connection *c, uint32_t id, const unsigned char *payload,
                        uint32_t length)
{
    if (!sdfd_token_matches(&b->srv->cfg, (const char *)payload, length)) {
        sdfd_bin_send_error(c, id, SDFD_EUNAUTHORIZED, "wrong token");
        c->closing = 1;
        return;
    }
    c->authenticated = 1;
    char *frame = malloc(SDF_PROTO_HEADER_SIZE);
    if (!frame)
        return;
    sdf_proto_encode_header(frame, SDF_PROTO_AUTH_OK, id, 0);
    sdfd_bin_enqueue(c, frame, SDF_PROTO_HEADER_SIZE);
}

/* ---- dispatch ---------------------------------------------------------------------------- */

void sdfd_bin_frame_kind(uint8_t type, sdfd_route *route, const char **what)
{
    *route = type == SDF_PROTO_QUERY          ? SDFD_ROUTE_BIN_QUERY
             : type == SDF_PROTO_VOLUME_QUERY ? SDFD_ROUTE_BIN_VOLUME_QUERY
                                              : SDFD_ROUTE_BIN_OTHER;
    *what = type == SDF_PROTO_QUERY          ? "QUERY"
            : type == SDF_PROTO_VOLUME_QUERY ? "VOLUME_QUERY"
            : type == SDF_PROTO_HELLO        ? "HELLO"
            : type == SDF_PROTO_LIST_MESHES  ? "LIST_MESHES"
            : type == SDF_PROTO_AUTH         ? "AUTH"
                                             : "UNKNOWN";
}

void sdfd_bin_handle_frame(sdfd_binary *b, connection *c, const sdf_proto_header *h,
                           const unsigned char *payload)
{
    const sdfd_config *cfg = &b->srv->cfg;
    sdfd_route route;
    const char *what;
    sdfd_bin_frame_kind(h->type, &route, &what);
    if ((h->type == SDF_PROTO_QUERY || h->type == SDF_PROTO_VOLUME_QUERY) && cfg->token &&
        cfg->auth_queries && !c->authenticated) {
        sdfd_bin_send_error(c, h->request_id, SDFD_EUNAUTHORIZED,
                            "this server needs AUTH with its token before queries");
        sdfd_bin_account(b, route, what, 401, 0, sdfd_now(), SDF_PROTO_HEADER_SIZE + h->length,
                         0);
        return;
    }
    if (h->type == SDF_PROTO_QUERY) {
        handle_query(b, c, h->request_id, payload, h->length);
        return;
    }
    if (h->type == SDF_PROTO_VOLUME_QUERY) {
        handle_volume_query(b, c, h->request_id, payload, h->length);
        return;
    }
    double start = sdfd_now();
    int status = 200;
    if (h->type == SDF_PROTO_HELLO) {
        sdf_proto_hello hello = {SDF_PROTO_VERSION, b->max_payload, (uint32_t)b->srv->cfg.max_points,
                                 "sdfd " SDFD_VERSION, strlen("sdfd " SDFD_VERSION)};
        char *frame = malloc(128);
        size_t n = frame ? sdf_proto_encode_hello_ok(frame, 128, h->request_id, &hello) : 0;
        if (n)
            sdfd_bin_enqueue(c, frame, n);
        else
            free(frame);
    } else if (h->type == SDF_PROTO_LIST_MESHES) {
        handle_list(b, c, h->request_id);
    } else if (h->type == SDF_PROTO_AUTH) {
        handle_auth(b, c, h->request_id, payload, h->length);
        status = c->authenticated ? 200 : 401;
    } else {
        sdfd_bin_send_error(c, h->request_id, SDFD_EPROTO, "unknown message type");
        status = 400;
    }
    sdfd_bin_account(b, route, what, status, 0, start, SDF_PROTO_HEADER_SIZE + h->length, 0);
}
