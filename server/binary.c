/* binary.c - the binary protocol listener: one thread polls the listening socket and every
 * connection (non-blocking), splits the byte stream into frames, and answers HELLO and
 * LIST_MESHES itself; a QUERY becomes a batcher job whose reply frame is built in place
 * (the result words sit right after the frame header, so nothing is copied) and appended to
 * the connection's output queue by the dispatcher thread, which wakes the poll loop through
 * an eventfd. Replies therefore leave in completion order, matched by request id.
 *
 * Limits: a frame's length is checked against max_payload before the input buffer grows;
 * at most 64 queries per connection are in flight and at most 64 MiB of replies wait unsent,
 * beyond which the connection is not read (TCP backpressure on a client that does not read); a connection idle mid-frame for the timeout is closed; a framing error
 * gets one ERROR frame and the connection closes after it is sent. A connection that goes
 * away with queries in flight is freed when the last of them completes. */
#define _GNU_SOURCE /* accept4 */
#include "binary.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <netinet/in.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include "log.h"
#include "proto.h"

#define MAX_IN_FLIGHT 64
#define INPUT_BASE (64 * 1024) /* a connection's input buffer between big frames */
#define MAX_QUEUED_OUT (64u << 20) /* unsent reply bytes before we stop reading */

typedef struct out_frame {
    struct out_frame *next;
    char *data;   /* frame bytes (malloc'd) */
    size_t len, sent;
} out_frame;

typedef struct connection connection;

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

struct connection {
    int fd;
    struct sockaddr_storage peer; /* for the per-address connection limit */
    unsigned char *in;
    size_t in_len, in_cap;
    double last_activity;
    int closing;                /* send what is queued, then close */
    int dead;                   /* socket closed; waiting for in-flight jobs */
    pthread_mutex_t lock;       /* out queue and in_flight: shared with the dispatcher */
    out_frame *out_head, *out_tail;
    size_t out_bytes;           /* queued, not yet sent */
    int in_flight;
    int authenticated;          /* sent AUTH with the --token */
    connection *next;
};

struct sdfd_binary {
    sdfd_server *srv;
    int listen_fd, wake_fd;
    pthread_t thread;
    atomic_int stop, quiesced;
    connection *conns;
    size_t conn_count;
    uint32_t max_payload;
};

static void wake(sdfd_binary *b)
{
    uint64_t one = 1;
    ssize_t unused = write(b->wake_fd, &one, sizeof one);
    (void)unused;
}

/* Queue a frame; takes ownership of data. Any thread. */
static void enqueue(connection *c, char *data, size_t len)
{
    out_frame *f = malloc(sizeof *f);
    if (!f) {
        free(data);
        return;
    }
    *f = (out_frame){NULL, data, len, 0};
    pthread_mutex_lock(&c->lock);
    if (c->out_tail)
        c->out_tail->next = f;
    else
        c->out_head = f;
    c->out_tail = f;
    c->out_bytes += len;
    pthread_mutex_unlock(&c->lock);
}

static void send_error(connection *c, uint32_t id, int err, const char *message)
{
    char *frame = malloc(512);
    if (!frame)
        return;
    size_t n = sdf_proto_encode_error(frame, 512, id, err, message);
    enqueue(c, frame, n);
}

/* One request: metrics and a log line, as the HTTP side does. */
static void account(sdfd_binary *b, sdfd_route route, const char *what, int status, size_t points,
                    double start, size_t bytes_in, size_t bytes_out)
{
    double seconds = sdfd_now() - start;
    sdfd_metrics_request(b->srv->metrics, route, status, seconds);
    sdfd_log_request("binary", what,
                     route == SDFD_ROUTE_BIN_QUERY          ? "query"
                     : route == SDFD_ROUTE_BIN_VOLUME_QUERY ? "volume_query"
                                                            : "other",
                     status, points, seconds * 1e6, bytes_in, bytes_out);
}

/* A request of connection c has been answered (or refused after it was counted). */
static void request_finished(sdfd_binary *b, connection *c)
{
    pthread_mutex_lock(&c->lock);
    c->in_flight--;
    pthread_mutex_unlock(&c->lock);
    atomic_fetch_sub(&b->srv->in_flight, 1);
}

/* ---- queries ----------------------------------------------------------------------------- */

static void query_done(sdfd_job *job)
{
    bin_job *bj = (bin_job *)job;
    connection *c = bj->conn;
    sdfd_binary *b = job->user;
    int status = job->status ? sdf_http_status(job->status) : 200;
    size_t len = SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX +
                 4 * sdf_proto_words(job->mode) * job->count;
    if (job->status) {
        send_error(c, bj->request_id, job->status, job->message);
        free(bj->frame);
    } else {
        enqueue(c, bj->frame, len);
    }
    account(b, SDFD_ROUTE_BIN_QUERY, "QUERY", status, job->count, bj->start, bj->bytes_in,
            job->status ? 0 : len);
    sdf_mesh_release(job->mesh);
    sdf_mesh_release(bj->volume);
    free(bj->points);
    free(bj);
    request_finished(b, c);
    wake(b);
}

/* Refuse a query: ERROR frame, metrics, log. */
static void refuse(sdfd_binary *b, connection *c, uint32_t id, int err, const char *message,
                   double start, size_t bytes_in)
{
    send_error(c, id, err, message);
    account(b, SDFD_ROUTE_BIN_QUERY, "QUERY", sdf_http_status(err), 0, start, bytes_in, 0);
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
        refuse(b, c, id, SDF_EUNAVAILABLE, "the server is shutting down", start, bytes_in);
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
        else if (rc == SDF_EBUSY)
            snprintf(message, sizeof message, "more than %zu points are waiting; retry later",
                     srv->cfg.max_queued_points);
        else
            snprintf(message, sizeof message, "%s", sdf_strerror(rc));
        refuse(b, c, id, rc, message, start, bytes_in);
        sdf_mesh_release(mesh);
        sdf_mesh_release(volume);
        free(bj->frame), free(bj->points), free(bj);
        request_finished(b, c);
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
            snprintf(message, sizeof message, "%s", sdf_strerror(rc));
        send_error(c, vj->request_id, rc, message);
        free(vj->frame);
    } else {
        enqueue(c, vj->frame, len);
    }
    account(b, SDFD_ROUTE_BIN_VOLUME_QUERY, "VOLUME_QUERY", rc ? sdf_http_status(rc) : 200,
            vj->count, vj->start, vj->bytes_in, rc ? 0 : len);
    sdfd_volume_release(vj->stored);
    free(vj->points);
    free(vj);
    request_finished(b, c);
    wake(b);
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
        send_error(c, id, rc ? rc : SDF_EUNAVAILABLE, rc ? why : "the server is shutting down");
        account(b, SDFD_ROUTE_BIN_VOLUME_QUERY, "VOLUME_QUERY",
                sdf_http_status(rc ? rc : SDF_EUNAVAILABLE), 0, start, bytes_in, 0);
        return;
    }
    snprintf(message, sizeof message, "%.*s", (int)q.name_len, q.name);
    volume_job *vj = calloc(1, sizeof *vj);
    if (vj && !(vj->stored = sdfd_volumes_get(srv->volumes, message))) {
        free(vj);
        snprintf(message, sizeof message, "no volume named '%.*s'", (int)q.name_len, q.name);
        send_error(c, id, SDF_ENOTFOUND, message);
        account(b, SDFD_ROUTE_BIN_VOLUME_QUERY, "VOLUME_QUERY", 404, 0, start, bytes_in, 0);
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
            rc = SDF_EUNAVAILABLE;
            request_finished(b, c);
        }
    }
    pthread_attr_destroy(&attr);
    if (rc) {
        if (vj) {
            sdfd_volume_release(vj->stored);
            free(vj->frame), free(vj->points), free(vj);
        }
        send_error(c, id, rc, rc == SDF_ENOMEM ? "out of memory" : "cannot start a worker thread");
        account(b, SDFD_ROUTE_BIN_VOLUME_QUERY, "VOLUME_QUERY", sdf_http_status(rc), 0, start,
                bytes_in, 0);
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
        enqueue(c, frame, size);
    else {
        free(frame);
        send_error(c, id, SDF_ENOMEM, "out of memory");
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
        send_error(c, id, SDF_EUNAUTHORIZED, "wrong token");
        c->closing = 1;
        return;
    }
    c->authenticated = 1;
    char *frame = malloc(SDF_PROTO_HEADER_SIZE);
    if (!frame)
        return;
    sdf_proto_encode_header(frame, SDF_PROTO_AUTH_OK, id, 0);
    enqueue(c, frame, SDF_PROTO_HEADER_SIZE);
}

static void handle_frame(sdfd_binary *b, connection *c, const sdf_proto_header *h,
                         const unsigned char *payload)
{
    const sdfd_config *cfg = &b->srv->cfg;
    if ((h->type == SDF_PROTO_QUERY || h->type == SDF_PROTO_VOLUME_QUERY) && cfg->token &&
        cfg->auth_queries && !c->authenticated) {
        send_error(c, h->request_id, SDF_EUNAUTHORIZED,
                   "this server needs AUTH with its token before queries");
        account(b, h->type == SDF_PROTO_QUERY ? SDFD_ROUTE_BIN_QUERY : SDFD_ROUTE_BIN_VOLUME_QUERY,
                h->type == SDF_PROTO_QUERY ? "QUERY" : "VOLUME_QUERY", 401, 0, sdfd_now(),
                SDF_PROTO_HEADER_SIZE + h->length, 0);
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
            enqueue(c, frame, n);
        else
            free(frame);
    } else if (h->type == SDF_PROTO_LIST_MESHES) {
        handle_list(b, c, h->request_id);
    } else if (h->type == SDF_PROTO_AUTH) {
        handle_auth(b, c, h->request_id, payload, h->length);
        status = c->authenticated ? 200 : 401;
    } else {
        send_error(c, h->request_id, SDF_EPROTO, "unknown message type");
        status = 400;
    }
    const char *what = h->type == SDF_PROTO_HELLO         ? "HELLO"
                       : h->type == SDF_PROTO_LIST_MESHES ? "LIST_MESHES"
                       : h->type == SDF_PROTO_AUTH        ? "AUTH"
                                                          : "UNKNOWN";
    account(b, SDFD_ROUTE_BIN_OTHER, what, status, 0, start, SDF_PROTO_HEADER_SIZE + h->length, 0);
}

/* ---- connections ------------------------------------------------------------------------- */

static int resize_input(sdfd_binary *b, connection *c, size_t cap);

/* Parse every complete frame in the input buffer. */
static void consume_input(sdfd_binary *b, connection *c)
{
    size_t off = 0;
    while (!c->closing && c->in_len - off >= SDF_PROTO_HEADER_SIZE) {
        pthread_mutex_lock(&c->lock);
        int busy = c->in_flight >= MAX_IN_FLIGHT || c->out_bytes >= MAX_QUEUED_OUT;
        pthread_mutex_unlock(&c->lock);
        if (busy)
            break; /* the rest waits for replies to go out */
        sdf_proto_header h;
        const char *why;
        int rc = sdf_proto_decode_header(c->in + off, c->in_len - off, b->max_payload, &h, &why);
        if (rc) { /* the stream cannot be trusted any more */
            send_error(c, 0, rc, why);
            c->closing = 1;
            break;
        }
        if (c->in_len - off - SDF_PROTO_HEADER_SIZE < h.length)
            break; /* the rest of this frame has not arrived */
        handle_frame(b, c, &h, c->in + off + SDF_PROTO_HEADER_SIZE);
        off += SDF_PROTO_HEADER_SIZE + h.length;
    }
    if (off) { /* c->in is NULL before the first read */
        memmove(c->in, c->in + off, c->in_len - off);
        c->in_len -= off;
        /* A big frame's room goes back to the budget once it is used. */
        if (c->in_cap > INPUT_BASE && c->in_len <= INPUT_BASE)
            resize_input(b, c, INPUT_BASE);
    }
}

/* How many bytes the input buffer needs for the frame being read (checked cap). */
static size_t input_need(const sdfd_binary *b, const connection *c)
{
    if (c->in_len < SDF_PROTO_HEADER_SIZE)
        return INPUT_BASE > c->in_cap ? INPUT_BASE : c->in_cap;
    sdf_proto_header h;
    if (sdf_proto_decode_header(c->in, c->in_len, b->max_payload, &h, NULL))
        return c->in_cap;
    size_t need = SDF_PROTO_HEADER_SIZE + (size_t)h.length;
    return need > INPUT_BASE ? need : INPUT_BASE;
}

/* Resize the input buffer to `cap` bytes, its growth counted against --max-buffered-bytes
 * (0, or -1 when the budget or memory says no). */
static int resize_input(sdfd_binary *b, connection *c, size_t cap)
{
    if (cap > c->in_cap && sdfd_buffer_reserve(b->srv, cap - c->in_cap))
        return -1;
    unsigned char *in = realloc(c->in, cap);
    if (!in) {
        if (cap > c->in_cap)
            sdfd_buffer_release(b->srv, cap - c->in_cap);
        return -1;
    }
    if (cap < c->in_cap)
        sdfd_buffer_release(b->srv, c->in_cap - cap);
    c->in = in, c->in_cap = cap;
    return 0;
}

static int read_input(sdfd_binary *b, connection *c)
{
    size_t need = input_need(b, c);
    if (need > c->in_cap && resize_input(b, c, need)) {
        /* Too many bytes held over all connections (or no memory): this frame is refused,
         * and the connection closed, since its payload cannot be skipped unread. */
        sdf_proto_header h;
        uint32_t id = c->in_len >= SDF_PROTO_HEADER_SIZE &&
                              !sdf_proto_decode_header(c->in, c->in_len, b->max_payload, &h, NULL)
                          ? h.request_id
                          : 0;
        char why[160];
        snprintf(why, sizeof why, SDFD_BUFFER_BUSY_FMT, b->srv->cfg.max_buffered_bytes);
        send_error(c, id, SDF_EBUSY, why);
        c->closing = 1;
        return 0;
    }
    ssize_t n = recv(c->fd, c->in + c->in_len, c->in_cap - c->in_len, 0);
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR))
        return -1;
    if (n > 0) {
        c->in_len += (size_t)n;
        c->last_activity = sdfd_now();
        consume_input(b, c);
    }
    return 0;
}

static int write_output(connection *c)
{
    for (;;) {
        pthread_mutex_lock(&c->lock);
        out_frame *f = c->out_head;
        pthread_mutex_unlock(&c->lock);
        if (!f)
            return 0;
        ssize_t n = send(c->fd, f->data + f->sent, f->len - f->sent, MSG_NOSIGNAL);
        if (n < 0)
            return errno == EAGAIN || errno == EINTR ? 0 : -1;
        c->last_activity = sdfd_now();
        f->sent += (size_t)n;
        if (f->sent < f->len)
            return 0;
        pthread_mutex_lock(&c->lock);
        c->out_head = f->next;
        if (!c->out_head)
            c->out_tail = NULL;
        c->out_bytes -= f->len;
        pthread_mutex_unlock(&c->lock);
        free(f->data);
        free(f);
    }
}

static void close_socket(sdfd_binary *b, connection *c)
{
    if (c->fd >= 0) {
        close(c->fd);
        c->fd = -1;
        b->conn_count--;
    }
    c->dead = 1;
    free(c->in); /* nothing reads it any more; its room goes back to the budget */
    c->in = NULL;
    sdfd_buffer_release(b->srv, c->in_cap);
    c->in_cap = c->in_len = 0;
}

static void free_connection(connection *c)
{
    for (out_frame *f = c->out_head, *next; f; f = next) {
        next = f->next;
        free(f->data);
        free(f);
    }
    pthread_mutex_destroy(&c->lock);
    free(c->in);
    free(c);
}

static int same_host(const struct sockaddr_storage *a, const struct sockaddr_storage *b)
{
    if (a->ss_family != b->ss_family)
        return 0;
    if (a->ss_family == AF_INET)
        return !memcmp(&((const struct sockaddr_in *)a)->sin_addr,
                       &((const struct sockaddr_in *)b)->sin_addr, sizeof(struct in_addr));
    if (a->ss_family == AF_INET6)
        return !memcmp(&((const struct sockaddr_in6 *)a)->sin6_addr,
                       &((const struct sockaddr_in6 *)b)->sin6_addr, sizeof(struct in6_addr));
    return 0;
}

static size_t connections_from(const sdfd_binary *b, const struct sockaddr_storage *peer)
{
    size_t n = 0;
    for (const connection *c = b->conns; c; c = c->next)
        n += !c->dead && same_host(&c->peer, peer);
    return n;
}

static void accept_connections(sdfd_binary *b)
{
    for (;;) {
        struct sockaddr_storage peer;
        socklen_t len = sizeof peer;
        int fd = accept4(b->listen_fd, (struct sockaddr *)&peer, &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0)
            return;
        if (b->conn_count >= b->srv->cfg.max_connections ||
            connections_from(b, &peer) >= b->srv->cfg.max_per_ip) {
            close(fd);
            continue;
        }
        connection *c = calloc(1, sizeof *c);
        if (!c) {
            close(fd);
            continue;
        }
        c->fd = fd;
        c->peer = peer;
        c->last_activity = sdfd_now();
        pthread_mutex_init(&c->lock, NULL);
        c->next = b->conns;
        b->conns = c;
        b->conn_count++;
    }
}

/* Drop closed connections whose jobs have all completed. */
static void reap(sdfd_binary *b)
{
    for (connection **link = &b->conns; *link;) {
        connection *c = *link;
        pthread_mutex_lock(&c->lock);
        int idle = c->in_flight == 0;
        pthread_mutex_unlock(&c->lock);
        if (c->dead && idle) {
            *link = c->next;
            free_connection(c);
        } else {
            link = &c->next;
        }
    }
}

static void *poll_loop(void *arg)
{
    sdfd_binary *b = arg;
    struct pollfd *fds = NULL;
    connection **owners = NULL;
    size_t cap = 0;
    while (!atomic_load(&b->stop)) {
        size_t need = b->conn_count + 2;
        if (need > cap) {
            cap = need * 2;
            fds = realloc(fds, cap * sizeof *fds);
            owners = realloc(owners, cap * sizeof *owners);
        }
        size_t n = 0;
        fds[n++] = (struct pollfd){b->wake_fd, POLLIN, 0};
        fds[n++] = (struct pollfd){atomic_load(&b->quiesced) ? -1 : b->listen_fd, POLLIN, 0};
        for (connection *c = b->conns; c; c = c->next) {
            if (c->dead)
                continue;
            pthread_mutex_lock(&c->lock);
            int room = c->in_flight < MAX_IN_FLIGHT && c->out_bytes < MAX_QUEUED_OUT;
            short events = (c->out_head ? POLLOUT : 0) | (!c->closing && room ? POLLIN : 0);
            pthread_mutex_unlock(&c->lock);
            owners[n] = c;
            fds[n++] = (struct pollfd){c->fd, events, 0};
        }
        poll(fds, n, 1000);
        if (fds[0].revents & POLLIN) {
            uint64_t v;
            ssize_t unused = read(b->wake_fd, &v, sizeof v);
            (void)unused;
        }
        if (fds[1].revents & POLLIN)
            accept_connections(b);
        double now = sdfd_now(), timeout = b->srv->cfg.timeout_seconds;
        for (size_t i = 2; i < n; i++) {
            connection *c = owners[i];
            short re = fds[i].revents;
            int fail = (re & (POLLERR | POLLNVAL)) != 0;
            if (!fail && (re & (POLLIN | POLLHUP)) && !c->closing)
                fail = read_input(b, c) != 0;
            else if (!fail && !c->closing)
                consume_input(b, c); /* frames held back by the in-flight limit */
            if (!fail && (re & POLLOUT))
                fail = write_output(c) != 0;
            pthread_mutex_lock(&c->lock);
            int drained = !c->out_head && c->in_flight == 0;
            pthread_mutex_unlock(&c->lock);
            int stalled = c->in_len > 0 && now - c->last_activity > timeout;
            if (fail || stalled || (c->closing && drained))
                close_socket(b, c);
        }
        reap(b);
    }
    free(fds);
    free(owners);
    return NULL;
}

int sdfd_binary_start(sdfd_server *srv, sdfd_binary **out)
{
    int port;
    int fd = sdfd_listen(srv->cfg.bin_addr, &port);
    if (fd < 0)
        return -1;
    sdfd_binary *b = calloc(1, sizeof *b);
    b->srv = srv;
    b->listen_fd = fd;
    b->wake_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    b->max_payload = (uint32_t)sdfd_max_payload(&srv->cfg);
    fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK); /* accept4 loops until EAGAIN */
    if (b->wake_fd < 0 || pthread_create(&b->thread, NULL, poll_loop, b)) {
        close(fd);
        free(b);
        return -1;
    }
    sdfd_log_listening("binary", srv->cfg.bin_addr, port);
    *out = b;
    return 0;
}

void sdfd_binary_quiesce(sdfd_binary *b)
{
    atomic_store(&b->quiesced, 1);
    wake(b);
}

/* Send what is still queued before closing: a reply counts as answered once queued, so
 * shutdown must not drop it. Blocking writes, bounded by the connection timeout. */
static void flush_connection(sdfd_binary *b, connection *c)
{
    if (c->fd < 0 || !c->out_head)
        return;
    fcntl(c->fd, F_SETFL, fcntl(c->fd, F_GETFL) & ~O_NONBLOCK);
    struct timeval tv = {(time_t)b->srv->cfg.timeout_seconds, 0};
    setsockopt(c->fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    for (;;) { /* stop on error or when a timed-out send made no progress */
        out_frame *before = c->out_head;
        size_t sent = before ? before->sent : 0;
        if (!before || write_output(c) != 0 || (c->out_head == before && before->sent == sent))
            return;
    }
}

void sdfd_binary_stop(sdfd_binary *b)
{
    if (!b)
        return;
    atomic_store(&b->stop, 1);
    wake(b);
    pthread_join(b->thread, NULL);
    for (connection *c = b->conns, *next; c; c = next) {
        next = c->next;
        flush_connection(b, c);
        if (c->fd >= 0)
            close(c->fd);
        free_connection(c);
    }
    close(b->listen_fd);
    close(b->wake_fd);
    free(b);
}
