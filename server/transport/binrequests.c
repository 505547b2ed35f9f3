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

#include "core/errors.h"
#include "core/log.h"
#include "ops/admission.h"
#include "ops/queries.h"
#include "transport/binrequests.h"

/* ---- queries: QUERY and VOLUME_QUERY, each one job answered in a frame built in place ---- */

typedef struct bin_job {
    sdfd_query query;               /* a QUERY's */
    sdfd_volume_query volume_query; /* a VOLUME_QUERY's */
    const sdfd_op *op;
    sdfd_binary *b;
    connection *conn;
    uint32_t request_id;
    char *frame;  /* header + result prefix + words */
    size_t frame_len;
    float *points;
    double start;
    size_t bytes_in;
} bin_job;

/* Refuse a request of `op` (NULL: an unknown frame type): ERROR frame, metrics, log. */
static void refuse(sdfd_binary *b, connection *c, const sdfd_op *op, uint32_t id, int err,
                   const char *message, double start, size_t bytes_in)
{
    sdfd_bin_send_error(c, id, err, message);
    sdfd_bin_account(b, op, sdfd_op_frame_name(op ? op->frame : 0), sdfd_http_status(err), 0,
                     start, bytes_in, 0);
}

/* The job's answer (status 0: its frame; else an ERROR frame with message) and its end. */
static void finish(bin_job *bj, int status, int refused, const char *message, size_t count)
{
    connection *c = bj->conn;
    sdfd_binary *b = bj->b;
    if (status) {
        sdfd_bin_send_error(c, bj->request_id, status, message);
        free(bj->frame);
    } else {
        sdfd_bin_enqueue(c, bj->frame, bj->frame_len);
    }
    sdfd_bin_account(b, bj->op, sdfd_op_frame_name(bj->op->frame),
                     status ? sdfd_http_status(status) : 200,
                     refused ? 0 : count, bj->start, bj->bytes_in, status ? 0 : bj->frame_len);
    sdfd_query_release(&bj->query);
    sdfd_volume_query_release(&bj->volume_query);
    free(bj->points);
    free(bj);
    sdfd_bin_request_finished(b, c); /* wakes the loop; b may be freed once it returns */
}

static void query_done(sdfd_job *job)
{
    bin_job *bj = job->user;
    int refused = bj->query.refused; /* by admission, after a load */
    finish(bj, job->status, refused, refused ? bj->query.refusal : job->message, job->count);
}

static void volume_query_done(sdfd_volume_query *vq)
{
    finish(vq->user, vq->status, vq->refused, vq->message, vq->count);
}

static void count_in_flight(sdfd_binary *b, connection *c)
{
    pthread_mutex_lock(&c->lock);
    c->in_flight++;
    pthread_mutex_unlock(&c->lock);
    atomic_fetch_add(&b->srv->in_flight, 1);
}

/* A job for `count` decoded points (copied: the input buffer moves on) of a payload of
 * `len` bytes, with its reply frame for `mode`'s words; NULL (and refused) when out of
 * memory. */
static bin_job *new_job(sdfd_binary *b, connection *c, const sdfd_op *op, uint32_t id,
                        size_t len, const float *points, uint32_t count, sdf_proto_mode mode,
                        double start)
{
    size_t bytes_in = SDF_PROTO_HEADER_SIZE + len, words = (size_t)sdf_proto_words(mode) * count;
    bin_job *bj = calloc(1, sizeof *bj);
    if (bj) {
        bj->frame_len = SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX + 4 * words;
        bj->frame = malloc(bj->frame_len);
        bj->points = malloc(12 * (size_t)count + 4);
    }
    if (!bj || !bj->frame || !bj->points) {
        if (bj)
            free(bj->frame), free(bj->points);
        free(bj);
        refuse(b, c, op, id, SDF_ENOMEM, "out of memory", start, bytes_in);
        return NULL;
    }
    memcpy(bj->points, points, 12 * (size_t)count);
    *bj = (bin_job){.op = op, .b = b, .conn = c, .request_id = id, .frame = bj->frame,
                    .frame_len = bj->frame_len, .points = bj->points, .start = start,
                    .bytes_in = bytes_in};
    return bj;
}

/* Hand the job to its handler: its words sit right after the frame's header. */
static void admit(bin_job *bj, sdf_proto_mode mode, uint32_t count)
{
    size_t head = sdf_proto_encode_result_head(bj->frame, bj->request_id, mode, count);
    uint32_t *words = (uint32_t *)(bj->frame + head);
    char message[SDFD_QUERY_MESSAGE_MAX];
    count_in_flight(bj->b, bj->conn); /* admission may end on a loader's thread */
    int rc;
    if (bj->op->id == SDFD_OP_QUERY) {
        bj->query.job.words = words;
        rc = sdfd_query_admit(bj->b->srv, &bj->query, message, sizeof message);
    } else {
        bj->volume_query.words = words;
        rc = sdfd_volume_query_admit(bj->b->srv, &bj->volume_query, message, sizeof message);
    }
    if (rc) /* nothing held after a refused admission */
        finish(bj, rc, 1, message, 0);
}

/* The frame's spelling of a query into the handler's terms (queries.h). */
static void handle_query(sdfd_binary *b, connection *c, const sdfd_op *op, uint32_t id,
                         const unsigned char *payload, size_t len, double start)
{
    sdf_proto_query d;
    const char *why;
    int rc = sdf_proto_decode_query(payload, len, (uint32_t)b->srv->cfg.max_points, &d, &why);
    if (rc) {
        refuse(b, c, op, id, rc, why, start, SDF_PROTO_HEADER_SIZE + len);
        return;
    }
    bin_job *bj = new_job(b, c, op, id, len, d.points, d.count, d.mode, start);
    if (!bj)
        return;
    bj->query = (sdfd_query){
        .mesh_name = d.name, .mesh_name_len = d.name_len, .smoothing_name = d.volume_name,
        .smoothing_name_len = d.volume_name_len,
        .job = {.mode = d.mode, .sign = d.sign, .filter = d.filter, .points = bj->points,
                .count = d.count, .done = query_done, .user = bj}};
    admit(bj, d.mode, d.count);
}

static void handle_volume_query(sdfd_binary *b, connection *c, const sdfd_op *op, uint32_t id,
                                const unsigned char *payload, size_t len, double start)
{
    sdf_proto_volume_query d;
    const char *why;
    int rc = sdf_proto_decode_volume_query(payload, len, (uint32_t)b->srv->cfg.max_points, &d,
                                           &why);
    if (rc) {
        refuse(b, c, op, id, rc, why, start, SDF_PROTO_HEADER_SIZE + len);
        return;
    }
    sdf_proto_mode mode = d.gradient ? SDF_MODE_GRADIENT : SDF_MODE_SIGNED;
    bin_job *bj = new_job(b, c, op, id, len, d.points, d.count, mode, start);
    if (!bj)
        return;
    bj->volume_query = (sdfd_volume_query){
        .volume_name = d.name, .volume_name_len = d.name_len, .interpolation = d.interpolation,
        .gradient = d.gradient, .points = bj->points, .count = d.count,
        .done = volume_query_done, .user = bj};
    admit(bj, mode, d.count);
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
        refuse(b, c, op, h->request_id, rc, msg, start, bytes_in);
        return;
    }
    int status = 200;
    switch (op->id) {
    case SDFD_OP_QUERY:
        handle_query(b, c, op, h->request_id, payload, h->length, start);
        return;
    case SDFD_OP_VOLUME_QUERY:
        handle_volume_query(b, c, op, h->request_id, payload, h->length, start);
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
