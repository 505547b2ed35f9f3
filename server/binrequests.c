/* binrequests.c - what the binary front end answers (PROTOCOL.md): QUERY and VOLUME_QUERY go
 * to the handlers (queries.h), as HTTP's queries do, with a reply frame built in place (the
 * result words sit right after the frame header, so nothing is copied) and queued when the
 * handler's done callback runs; HELLO, LIST_MESHES and AUTH are answered at once on the loop's
 * thread. The connections themselves (epoll, framing, limits) are binary.c's, their reply
 * queues binconn.c's. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "binrequests.h"
#include "errors.h"
#include "log.h"
#include "admission.h"
#include "queries.h"

/* ---- queries ----------------------------------------------------------------------------- */

typedef struct bin_job {
    sdfd_query query;
    sdfd_binary *b;
    connection *conn;
    uint32_t request_id;
    char *frame;  /* header + result prefix + words */
    float *points;
    double start;
    size_t bytes_in;
} bin_job;

static void query_done(sdfd_job *job)
{
    bin_job *bj = job->user;
    connection *c = bj->conn;
    sdfd_binary *b = bj->b;
    int status = job->status ? sdfd_http_status(job->status) : 200;
    size_t len = SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX +
                 4 * sdf_proto_words(job->mode) * job->count;
    int refused = bj->query.refused; /* by admission, after a load */
    if (job->status) {
        sdfd_bin_send_error(c, bj->request_id, job->status,
                            refused ? bj->query.refusal : job->message);
        free(bj->frame);
    } else {
        sdfd_bin_enqueue(c, bj->frame, len);
    }
    sdfd_bin_account(b, sdfd_op_get(SDFD_OP_QUERY), "QUERY", status, refused ? 0 : job->count,
                     bj->start, bj->bytes_in, job->status ? 0 : len);
    sdfd_query_release(&bj->query);
    free(bj->points);
    free(bj);
    sdfd_bin_request_finished(b, c); /* wakes the loop; b may be freed once it returns */
}

/* Refuse a request: ERROR frame, metrics, log. */
static void refuse(sdfd_binary *b, connection *c, const sdfd_op *op, const char *what,
                   uint32_t id, int err, const char *message, double start, size_t bytes_in)
{
    sdfd_bin_send_error(c, id, err, message);
    sdfd_bin_account(b, op, what, sdfd_http_status(err), 0, start, bytes_in, 0);
}

static void count_in_flight(sdfd_binary *b, connection *c)
{
    pthread_mutex_lock(&c->lock);
    c->in_flight++;
    pthread_mutex_unlock(&c->lock);
    atomic_fetch_add(&b->srv->in_flight, 1);
}

/* The frame's spelling of a query into the handler's terms (queries.h). */
static void handle_query(sdfd_binary *b, connection *c, uint32_t id, const unsigned char *payload,
                         size_t len)
{
    sdfd_server *srv = b->srv;
    double start = sdfd_now();
    size_t bytes_in = SDF_PROTO_HEADER_SIZE + len;
    sdf_proto_query d;
    const char *why;
    char message[300];
#define REFUSE(err, text) \
    refuse(b, c, sdfd_op_get(SDFD_OP_QUERY), "QUERY", id, err, text, start, bytes_in)
    int rc = sdf_proto_decode_query(payload, len, (uint32_t)srv->cfg.max_points, &d, &why);
    if (rc) {
        REFUSE(rc, why);
        return;
    }
    bin_job *bj = calloc(1, sizeof *bj);
    size_t words = (size_t)sdf_proto_words(d.mode) * d.count;
    if (bj) {
        bj->frame = malloc(SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX + 4 * words);
        bj->points = malloc(12 * (size_t)d.count + 4);
    }
    if (!bj || !bj->frame || !bj->points) {
        if (bj)
            free(bj->frame), free(bj->points);
        free(bj);
        REFUSE(SDF_ENOMEM, "out of memory");
        return;
    }
    memcpy(bj->points, d.points, 12 * (size_t)d.count); /* the input buffer will move on */
    size_t head = sdf_proto_encode_result_head(bj->frame, id, d.mode, d.count);
    bj->query = (sdfd_query){
        .mesh_name = d.name, .mesh_name_len = d.name_len, .smoothing_name = d.volume_name,
        .smoothing_name_len = d.volume_name_len,
        .job = {.mode = d.mode, .sign = d.sign, .filter = d.filter, .points = bj->points,
                .count = d.count, .words = (uint32_t *)(bj->frame + head), .done = query_done,
                .user = bj}};
    bj->b = b;
    bj->conn = c;
    bj->request_id = id;
    bj->start = start;
    bj->bytes_in = bytes_in;
    count_in_flight(b, c); /* admission may end on a loader's thread */
    if ((rc = sdfd_query_admit(srv, &bj->query, message, sizeof message))) {
        REFUSE(rc, message);
        free(bj->frame), free(bj->points), free(bj);
        sdfd_bin_request_finished(b, c);
    }
#undef REFUSE
}

/* ---- volume queries (the handler runs them on a thread of their own), answered like
 * queries ---------------------------------------------------------------------------------- */

typedef struct volume_job {
    sdfd_volume_query query;
    sdfd_binary *b;
    connection *conn;
    uint32_t request_id;
    float *points;
    char *frame;
    double start;
    size_t bytes_in;
} volume_job;

static void volume_query_done(sdfd_volume_query *vq)
{
    volume_job *vj = vq->user;
    connection *c = vj->conn;
    sdfd_binary *b = vj->b;
    size_t len = SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX +
                 4 * (vq->gradient ? 4 : 1) * vq->count;
    if (vq->status) {
        sdfd_bin_send_error(c, vj->request_id, vq->status, vq->message);
        free(vj->frame);
    } else {
        sdfd_bin_enqueue(c, vj->frame, len);
    }
    sdfd_bin_account(b, sdfd_op_get(SDFD_OP_VOLUME_QUERY), "VOLUME_QUERY",
                     vq->status ? sdfd_http_status(vq->status) : 200,
                     vq->refused ? 0 : vq->count, vj->start, vj->bytes_in,
                     vq->status ? 0 : len);
    sdfd_volume_query_release(vq);
    free(vj->points);
    free(vj);
    sdfd_bin_request_finished(b, c); /* wakes the loop; b may be freed once it returns */
}

static void handle_volume_query(sdfd_binary *b, connection *c, uint32_t id,
                                const unsigned char *payload, size_t len)
{
    sdfd_server *srv = b->srv;
    double start = sdfd_now();
    size_t bytes_in = SDF_PROTO_HEADER_SIZE + len;
    sdf_proto_volume_query d;
    const char *why;
    char message[300];
#define REFUSE(err, text) \
    refuse(b, c, sdfd_op_get(SDFD_OP_VOLUME_QUERY), "VOLUME_QUERY", id, err, text, start, \
           bytes_in)
    int rc = sdf_proto_decode_volume_query(payload, len, (uint32_t)srv->cfg.max_points, &d, &why);
    if (rc) {
        REFUSE(rc, why);
        return;
    }
    volume_job *vj = calloc(1, sizeof *vj);
    if (vj) {
        vj->frame = malloc(SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX +
                           4 * (d.gradient ? 4 : 1) * (size_t)d.count);
        vj->points = malloc(12 * (size_t)d.count + 4);
    }
    if (!vj || !vj->frame || !vj->points) {
        if (vj)
            free(vj->frame), free(vj->points);
        free(vj);
        REFUSE(SDF_ENOMEM, "out of memory");
        return;
    }
    memcpy(vj->points, d.points, 12 * (size_t)d.count); /* the input buffer moves on */
    size_t head = sdf_proto_encode_result_head(
        vj->frame, id, d.gradient ? SDF_MODE_GRADIENT : SDF_MODE_SIGNED, d.count);
    vj->query = (sdfd_volume_query){
        .volume_name = d.name, .volume_name_len = d.name_len, .interpolation = d.interpolation,
        .gradient = d.gradient, .points = vj->points, .count = d.count,
        .words = (uint32_t *)(vj->frame + head), .done = volume_query_done, .user = vj};
    vj->b = b;
    vj->conn = c;
    vj->request_id = id;
    vj->start = start;
    vj->bytes_in = bytes_in;
    count_in_flight(b, c); /* admission may end on a loader's thread */
    if ((rc = sdfd_volume_query_admit(srv, &vj->query, message, sizeof message))) {
        REFUSE(rc, message);
        free(vj->frame), free(vj->points), free(vj);
        sdfd_bin_request_finished(b, c);
    }
#undef REFUSE
}

static void handle_list(sdfd_binary *b, connection *c, uint32_t id)
{
    sdfd_mesh_summary *list;
    size_t n = sdfd_cache_list_meshes(b->srv->cache, &list);
    sdf_proto_mesh_entry *entries = calloc(n + 1, sizeof *entries);
    for (size_t i = 0; entries && i < n; i++)
        entries[i] = (sdf_proto_mesh_entry){list[i].name, strlen(list[i].name), list[i].triangles,
                                            (uint8_t)list[i].closed, (uint8_t)list[i].sign};
    size_t size = entries ? sdf_proto_meshes_size(entries, n) : 0;
    char *frame = size ? malloc(size) : NULL;
    if (frame && sdf_proto_encode_meshes(frame, size, id, entries, n) == size)
        sdfd_bin_enqueue(c, frame, size);
    else {
        free(frame);
        sdfd_bin_send_error(c, id, SDF_ENOMEM, "out of memory");
    }
    free(entries);
    free(list);
}

static void handle_hello(sdfd_binary *b, connection *c, uint32_t id)
{
    sdf_proto_hello hello = {SDF_PROTO_VERSION, b->max_payload, (uint32_t)b->srv->cfg.max_points,
                             "sdfd " SDFD_VERSION, strlen("sdfd " SDFD_VERSION)};
    char *frame = malloc(128);
    size_t n = frame ? sdf_proto_encode_hello_ok(frame, 128, id, &hello) : 0;
    if (n)
        sdfd_bin_enqueue(c, frame, n);
    else
        free(frame);
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

/* Admission (admission.h) in the protocol's words, then the operation. */
void sdfd_bin_handle_frame(sdfd_binary *b, connection *c, const sdf_proto_header *h,
                           const unsigned char *payload)
{
    const sdfd_op *op;
    const char *what;
    sdfd_bin_frame_kind(h->type, &op, &what);
    double start = sdfd_now();
    size_t bytes_in = SDF_PROTO_HEADER_SIZE + h->length;
    char msg[300];
    int rc = op ? sdfd_admit(b->srv, op, c->authenticated, msg, sizeof msg) : SDFD_EPROTO;
    if (rc) {
        if (rc == SDFD_EUNAUTHORIZED)
            snprintf(msg, sizeof msg, "this server needs AUTH with its token before queries");
        else if (rc == SDFD_EPROTO)
            snprintf(msg, sizeof msg, "unknown message type");
        refuse(b, c, op, what, h->request_id, rc, msg, start, bytes_in);
        return;
    }
    int status = 200;
    switch (op->id) {
    case SDFD_OP_QUERY:
        handle_query(b, c, h->request_id, payload, h->length);
        return;
    case SDFD_OP_VOLUME_QUERY:
        handle_volume_query(b, c, h->request_id, payload, h->length);
        return;
    case SDFD_OP_HELLO:
        handle_hello(b, c, h->request_id);
        break;
    case SDFD_OP_MESH_LIST:
        handle_list(b, c, h->request_id);
        break;
    default: /* SDFD_OP_AUTH */
        handle_auth(b, c, h->request_id, payload, h->length);
        status = c->authenticated ? 200 : 401;
    }
    sdfd_bin_account(b, op, what, status, 0, start, bytes_in, 0);
}
