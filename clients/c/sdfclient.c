/* sdfclient.c - libsdfclient (sdfclient.h): one non-blocking connection to sdfd's binary
 * port (transport.c: TCP, or TLS over it), framed with proto/'s codec. Replies are read by
 * a small state machine (header, then a RESULT's 8-byte prefix and its words straight into
 * the caller's buffer, or any other frame into a bounded heap block), so a reply never needs
 * a copy and a send that finds the socket full can read replies meanwhile: a client that
 * sends far more requests than the server keeps in flight (64) then never deadlocks with it.
 * Requests in flight live in a table indexed by request id minus the oldest id, as ids are
 * handed out in order.
 *
 * Re-sending (sdfclient.h): a re-sendable request keeps a copy of its frame's header and
 * prefix and a pointer to the caller's points. When the connection is lost, reconnect()
 * replaces it in place (the table stays; the reader starts afresh) and sends every
 * unanswered request again. It may run deep inside a send that was itself interrupted: the
 * connection's generation tells that send its frame already went out whole on the new one. */
#include "sdfclient.h"

#include <errno.h>
#include <limits.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/uio.h>
#include <time.h>

#include "proto.h"
#include "transport.h"

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "libsdfclient passes points and results through as the protocol's little-endian words"
#endif

/* The shared codes must keep libsdf's values (sdfclient.h promises it). */
_Static_assert((int)SDFC_EINVAL == (int)SDF_EINVAL && (int)SDFC_ENOMEM == (int)SDF_ENOMEM &&
                   (int)SDFC_EIO == (int)SDF_EIO && (int)SDFC_ELIMIT == (int)SDF_ELIMIT &&
                   (int)SDFC_EPROTO == (int)SDF_EPROTO,
               "SDFC_E* codes shared with sdf.h must have its values");
_Static_assert((int)SDFC_CLOSEST == (int)SDF_MODE_CLOSEST &&
                   (int)SDFC_FILTERED_GRADIENT == (int)SDF_MODE_FILTERED_GRADIENT &&
                   (int)SDFC_SIGN_NONE == (int)SDF_SIGN_NONE,
               "sdfc modes and signs are the wire codes");

/* A reply other than a RESULT (HELLO_OK, MESHES, ERROR, AUTH_OK) is read into the heap: at
 * most this many bytes, about 200,000 mesh names. */
#define CTRL_MAX_PAYLOAD ((uint32_t)64 << 20)

enum { FREE = 0, IN_FLIGHT, DONE };

typedef struct pending {
    int state;
    int status;              /* once DONE: 0 or SDFC_ESERVER */
    uint8_t reply_type;      /* the frame type that answers it */
    int resent;              /* sent again on a new connection already */
    unsigned char *frame;    /* re-sendable requests: header and prefix (or the whole frame
                                but points), owned; NULL: never re-sent */
    size_t frame_len;
    const void *points;      /* and the caller's points */
    size_t points_len;
    unsigned char head[24];  /* a RESULT's expected header and prefix */
    unsigned char *result;   /* a query's caller buffer (expect bytes) */
    size_t expect;
    unsigned char *payload;  /* other replies: the payload, owned */
    size_t payload_len;
    sdfc_server_err *err;    /* an ERROR reply, owned */
    uint64_t done_seq;       /* order of completion, for sdfc_wait_any */
} pending;

/* Where the reader stands in the current frame. */
typedef struct reader {
    unsigned char hdr[24];   /* header, then a RESULT's prefix */
    size_t got;              /* bytes of the current frame read so far */
    int routed;              /* the header is in and decoded */
    sdf_proto_header h;      /* h.request_id: the request it answers (0: the connection);
                                looked up anew each time, as sending may move the table */
    unsigned char *buf;      /* non-RESULT payload */
} reader;

struct sdfc_client {
    sdfc__conn conn;
    unsigned generation;     /* connections replaced so far */
    int broken;              /* sticky error code, 0 while usable */
    int reply_timeout_ms;
    int connect_timeout_ms;
    char *host;              /* where to connect again, and how */
    int port;
    sdfc__tls *tls;
    int resend;
    int reconnecting;
    char *token;             /* the last token the server took; NULL: none */
    size_t token_len;
    sdfc_stats stats;
    uint32_t max_points;     /* from HELLO; 0 = unknown */
    uint32_t max_payload;
    uint32_t next_id;
    pending *pend;           /* pend[head .. head + n) are ids base_id .. */
    size_t head, n, cap;
    uint32_t base_id;
    size_t in_flight;
    uint64_t done_seq;
    reader rx;
    sdfc_server_err err;
};

const char *sdfc_strerror(int err)
{
    switch (err) {
    case SDFC_OK: return "success";
    case SDFC_EINVAL: return "invalid argument";
    case SDFC_ENOMEM: return "out of memory";
    case SDFC_EIO: return "socket error";
    case SDFC_ELIMIT: return "size limit exceeded";
    case SDFC_EPROTO: return "malformed reply from the server";
    case SDFC_ESERVER: return "the server refused the request";
    case SDFC_ECONNECT: return "cannot connect to the server";
    case SDFC_ETIMEDOUT: return "timed out";
    case SDFC_ECLOSED: return "the server closed the connection";
    case SDFC_ENOREQUEST: return "no such request in flight";
    case SDFC_ETLS: return "the TLS handshake or a TLS record failed";
    case SDFC_ECERT: return "the server's certificate is not trusted (not signed by the CA "
                            "file's CAs, expired, or for another host)";
    default: return "unknown error";
    }
}

static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

static int set_broken(sdfc_client *c, int code)
{
    if (!c->broken)
        c->broken = code;
    return c->broken;
}

/* ---- modes and names --------------------------------------------------------------------- */

int sdfc_mode_from_name(const char *name, sdfc_mode *out)
{
    sdf_proto_mode m;
    if (!out || sdf_proto_mode_from_name(name, &m))
        return SDFC_EINVAL;
    *out = (sdfc_mode)m;
    return 0;
}

/* sdfc_interpolation's names, in wire order. */
static const char *const interpolation_names[] = {"trilinear", "nearest", "hermite", "default"};

int sdfc_interpolation_from_name(const char *name, sdfc_interpolation *out)
{
    for (int i = 0; name && out && i < 4; i++) {
        if (!strcmp(name, interpolation_names[i])) {
            *out = (sdfc_interpolation)i;
            return 0;
        }
    }
    return SDFC_EINVAL;
}

int sdfc_sign_from_name(const char *name, sdfc_sign *out)
{
    static const char *const names[] = {"auto", "pseudonormal", "winding", "raycast", "none"};
    for (int i = 0; name && out && i < 5; i++) {
        if (!strcmp(name, names[i])) {
            *out = (sdfc_sign)i;
            return 0;
        }
    }
    return SDFC_EINVAL;
}

unsigned sdfc_words(sdfc_mode mode) { return sdf_proto_words((sdf_proto_mode)mode); }

size_t sdfc_result_size(sdfc_mode mode, uint32_t count)
{
    return (size_t)4 * sdfc_words(mode) * count;
}

/* ---- connecting -------------------------------------------------------------------------- */

int sdfc_connect(const char *host, int port, const sdfc_options *opts, sdfc_client **out)
{
    if (!out)
        return SDFC_EINVAL;
    *out = NULL;
    sdfc_options o = opts ? *opts : (sdfc_options){0};
    if (!host || !*host || port <= 0 || port > 65535 || (o.ca_file && !o.tls))
        return SDFC_EINVAL;
    sdfc_client *c = calloc(1, sizeof *c);
    if (!c || !(c->host = strdup(host))) {
        free(c);
        return SDFC_ENOMEM;
    }
    c->conn.fd = -1;
    c->port = port;
    c->resend = !!o.resend;
    c->connect_timeout_ms = o.connect_timeout_ms ? o.connect_timeout_ms : 10000;
    c->reply_timeout_ms = o.reply_timeout_ms ? o.reply_timeout_ms : 120000;
    c->next_id = c->base_id = 1;
    int rc = o.tls ? sdfc__tls_new(o.ca_file, &c->tls) : 0;
    if (!rc)
        rc = sdfc__conn_open(&c->conn, host, port, c->tls, c->connect_timeout_ms);
    if (!rc) {
        c->stats.connects = 1;
        if (o.token)
            rc = sdfc_auth(c, o.token, strlen(o.token));
    }
    if (rc) {
        int saved = errno;
        sdfc_close(c);
        errno = saved;
        return rc;
    }
    *out = c;
    return 0;
}

int sdfc_get_stats(const sdfc_client *c, sdfc_stats *out)
{
    if (!c || !out)
        return SDFC_EINVAL;
    *out = c->stats;
    return 0;
}

static void free_entry(pending *p)
{
    free(p->payload);
    free(p->err);
    free(p->frame);
    *p = (pending){0};
}

void sdfc_close(sdfc_client *c)
{
    if (!c)
        return;
    sdfc__conn_close(&c->conn);
    sdfc__tls_free(c->tls);
    for (size_t i = 0; i < c->n; i++)
        free_entry(&c->pend[c->head + i]);
    free(c->pend);
    free(c->rx.buf);
    free(c->host);
    free(c->token);
    free(c);
}

const sdfc_server_err *sdfc_server_error(const sdfc_client *c) { return c ? &c->err : NULL; }

size_t sdfc_in_flight(const sdfc_client *c) { return c ? c->in_flight : 0; }

/* Start of every call: the error of the last one is gone, unless the handle is broken. */
static int begin(sdfc_client *c)
{
    if (!c)
        return SDFC_EINVAL;
    if (!c->broken)
        c->err = (sdfc_server_err){0};
    return c->broken;
}

/* ---- the table of requests in flight ----------------------------------------------------- */

static pending *lookup(sdfc_client *c, uint32_t id)
{
    uint32_t i = id - c->base_id;
    if (id == 0 || i >= c->n)
        return NULL;
    pending *p = &c->pend[c->head + i];
    return p->state == FREE ? NULL : p;
}

/* A new entry for the next id; NULL when out of memory or ids. */
static pending *add_entry(sdfc_client *c, uint32_t *id)
{
    if (c->next_id == UINT32_MAX)
        return NULL;
    if (c->head + c->n == c->cap) {
        if (c->head > 0) {
            memmove(c->pend, c->pend + c->head, c->n * sizeof *c->pend);
            c->head = 0;
        }
        if (c->n == c->cap) {
            size_t cap = c->cap ? 2 * c->cap : 64;
            pending *grown = realloc(c->pend, cap * sizeof *grown);
            if (!grown)
                return NULL;
            c->pend = grown;
            c->cap = cap;
        }
    }
    if (c->n == 0)
        c->base_id = c->next_id;
    pending *p = &c->pend[c->head + c->n++];
    *p = (pending){.state = IN_FLIGHT};
    *id = c->next_id++;
    c->in_flight++;
    return p;
}

/* Hand a finished entry back: its error (if any) becomes the handle's; the table's head
 * moves past entries already given back. */
static int claim(sdfc_client *c, pending *p)
{
    int status = p->status;
    if (p->err)
        c->err = *p->err;
    free_entry(p);
    c->in_flight--;
    while (c->n > 0 && c->pend[c->head].state == FREE) {
        c->head++;
        c->n--;
        c->base_id++;
    }
    if (c->n == 0)
        c->head = 0;
    return status;
}

/* An entry whose request could not be sent (a full handle fails anyway; this keeps the
 * table honest for sdfc_in_flight). */
static void drop(sdfc_client *c, pending *p) { (void)claim(c, p); }

/* ---- reading replies --------------------------------------------------------------------- */

static void copy_str(char *dst, size_t cap, const char *s, size_t len)
{
    if (len >= cap)
        len = cap - 1;
    memcpy(dst, s, len);
    dst[len] = 0;
}

/* The current frame's header is in: decide where its payload goes. */
static int rx_route(sdfc_client *c)
{
    reader *r = &c->rx;
    const char *why;
    if (sdf_proto_decode_header(r->hdr, SDF_PROTO_HEADER_SIZE, UINT32_MAX, &r->h, &why))
        return set_broken(c, SDFC_EPROTO);
    r->routed = 1;
    pending *p = lookup(c, r->h.request_id);
    if (p && p->state != IN_FLIGHT)
        return set_broken(c, SDFC_EPROTO); /* a second reply to one request */
    if (!p && !(r->h.request_id == 0 && r->h.type == SDF_PROTO_ERROR))
        return set_broken(c, SDFC_EPROTO); /* a reply to nothing we asked */
    if (r->h.type == SDF_PROTO_RESULT) {
        if (p->reply_type != SDF_PROTO_RESULT || r->h.length != SDF_PROTO_RESULT_PREFIX + p->expect)
            return set_broken(c, SDFC_EPROTO);
        return 0;
    }
    if (r->h.type != SDF_PROTO_ERROR && (!p || r->h.type != p->reply_type))
        return set_broken(c, SDFC_EPROTO);
    if (r->h.length > CTRL_MAX_PAYLOAD)
        return set_broken(c, SDFC_ELIMIT);
    r->buf = malloc(r->h.length ? r->h.length : 1);
    return r->buf ? 0 : set_broken(c, SDFC_ENOMEM);
}

static int store_error(sdfc_client *c, sdfc_server_err *dst)
{
    reader *r = &c->rx;
    sdf_proto_error e;
    const char *why;
    if (sdf_proto_decode_error(r->buf, r->h.length, &e, &why))
        return set_broken(c, SDFC_EPROTO);
    dst->status = e.status;
    copy_str(dst->code, sizeof dst->code, e.code, e.code_len);
    copy_str(dst->message, sizeof dst->message, e.message, e.message_len);
    return 0;
}

/* The current frame is in full: file it with its request. */
static int rx_finish(sdfc_client *c)
{
    reader *r = &c->rx;
    pending *p = lookup(c, r->h.request_id);
    int rc = 0;
    if (r->h.type == SDF_PROTO_RESULT) {
        /* header bytes but the flags (receivers ignore them), then the prefix */
        if (memcmp(r->hdr, p->head, 6) || memcmp(r->hdr + 8, p->head + 8, 16))
            rc = set_broken(c, SDFC_EPROTO);
    } else if (r->h.type == SDF_PROTO_ERROR) {
        if (!p) { /* about the connection, which the server now closes */
            rc = store_error(c, &c->err);
            rc = set_broken(c, rc ? rc : SDFC_ECLOSED);
        } else if (!(p->err = calloc(1, sizeof *p->err))) {
            rc = set_broken(c, SDFC_ENOMEM);
        } else if (!(rc = store_error(c, p->err))) {
            p->status = SDFC_ESERVER;
        }
    } else {
        p->payload = r->buf;
        p->payload_len = r->h.length;
        r->buf = NULL;
    }
    free(r->buf);
    r->buf = NULL;
    r->got = 0;
    r->routed = 0;
    if (p && !rc) {
        p->state = DONE;
        p->done_seq = ++c->done_seq;
    }
    return rc;
}

/* Where the next bytes of the current frame go, and how many are wanted. */
static unsigned char *rx_target(sdfc_client *c, size_t *want)
{
    reader *r = &c->rx;
    size_t hs = SDF_PROTO_HEADER_SIZE;
    if (r->got < hs) {
        *want = hs - r->got;
        return r->hdr + r->got;
    }
    size_t at = r->got - hs;
    if (r->h.type == SDF_PROTO_RESULT) {
        if (at < SDF_PROTO_RESULT_PREFIX) {
            *want = SDF_PROTO_RESULT_PREFIX - at;
            return r->hdr + r->got;
        }
        at -= SDF_PROTO_RESULT_PREFIX;
        pending *p = lookup(c, r->h.request_id);
        *want = p->expect - at;
        return p->result + at;
    }
    *want = r->h.length - at;
    return r->buf + at;
}

static int conn_lost(sdfc_client *c, int code);

/* A failed send or receive (errno) as the handle's error; a peer that went away may have
 * its connection replaced. */
static int io_failed(sdfc_client *c, int err)
{
    if (err == ECONNRESET || err == EPIPE)
        return conn_lost(c, SDFC_ECLOSED);
    return set_broken(c, err == EPROTO ? SDFC_ETLS : SDFC_EIO);
}

/* Read what the connection holds without blocking; *frames counts the frames completed. */
static int rx_pump(sdfc_client *c, int *frames)
{
    reader *r = &c->rx;
    for (;;) {
        if (c->broken)
            return c->broken;
        int rc;
        if (r->got == SDF_PROTO_HEADER_SIZE && !r->routed && (rc = rx_route(c)))
            return rc;
        size_t want = 0;
        unsigned char *dst = rx_target(c, &want);
        if (want == 0 && r->got >= SDF_PROTO_HEADER_SIZE) {
            if ((rc = rx_finish(c)))
                return rc;
            ++*frames;
            continue;
        }
        errno = 0;
        ssize_t got = sdfc__conn_recv(&c->conn, dst, want);
        if (got <= 0 && errno != EINTR && *frames)
            return 0; /* the frames before an end or error count first; the next call sees it */
        if (got == 0 && (rc = conn_lost(c, SDFC_ECLOSED)))
            return rc;
        if (got < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                return 0;
            if ((rc = io_failed(c, errno)))
                return rc;
        }
        if (got > 0)
            r->got += (size_t)got;
    }
}

/* Wait for `events` on the connection until `deadline` (now_ms's clock; no limit when the
 * reply timeout is negative): 0, or the connection marked broken with SDFC_ETIMEDOUT or
 * SDFC_EIO. */
static int wait_deadline(sdfc_client *c, double deadline, short events)
{
    int left = -1;
    if (c->reply_timeout_ms >= 0) {
        double l = deadline - now_ms();
        if (l <= 0)
            return set_broken(c, SDFC_ETIMEDOUT);
        left = l > INT_MAX ? INT_MAX : (int)l + 1;
    }
    return sdfc__conn_wait(&c->conn, events, left) < 0 ? set_broken(c, SDFC_EIO) : 0;
}


/* Block until at least one more frame completes, or the reply timeout passes. */
static int rx_one(sdfc_client *c)
{
    double deadline = now_ms() + c->reply_timeout_ms;
    for (;;) {
        int frames = 0, rc = rx_pump(c, &frames);
        if (rc || frames)
            return rc;
        if ((rc = wait_deadline(c, deadline, POLLIN)))
            return rc;
    }
}

/* ---- sending ----------------------------------------------------------------------------- */

/* Send the iovecs in full; while the socket is full, read replies. When the connection is
 * replaced meanwhile, the request these iovecs hold went out again whole on the new one
 * (it is in the table, re-sendable, or the handle would be broken): nothing is left to do. */
static int tx(sdfc_client *c, struct iovec *iov, int iovcnt)
{
    unsigned generation = c->generation;
    double deadline = now_ms() + c->reply_timeout_ms;
    while (iovcnt > 0) {
        ssize_t sent = sdfc__conn_send(&c->conn, iov, iovcnt);
        if (sent < 0 && errno == EINTR)
            continue;
        if (sent < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
            int saved = errno, frames = 0;
            rx_pump(c, &frames); /* a closing server may have said why: keep its ERROR */
            if (c->broken || c->generation != generation)
                return c->broken;
            return io_failed(c, saved);
        }
        if (sent < 0) {
            int frames = 0, rc = rx_pump(c, &frames);
            if (rc || c->generation != generation)
                return rc;
            if (frames)
                deadline = now_ms() + c->reply_timeout_ms;
            if ((rc = wait_deadline(c, deadline, POLLIN | POLLOUT)))
                return rc;
            continue;
        }
        deadline = now_ms() + c->reply_timeout_ms;
        size_t n = (size_t)sent;
        while (iovcnt > 0 && n >= iov->iov_len) {
            n -= iov->iov_len;
            iov++;
            iovcnt--;
        }
        if (iovcnt > 0) {
            iov->iov_base = (char *)iov->iov_base + n;
            iov->iov_len -= n;
        }
    }
    return 0;
}

/* Keep what re-sending `p` needs: a copy of `frame`, and `points` by reference. */
static int keep_frame(pending *p, const void *frame, size_t len, const void *points,
                      size_t points_len)
{
    if (!(p->frame = malloc(len)))
        return SDFC_ENOMEM;
    memcpy(p->frame, frame, len);
    p->frame_len = len;
    p->points = points;
    p->points_len = points_len;
    return 0;
}

/* ---- replacing a lost connection (sdfclient.h, "Re-sending") ----------------------------- */

static int call(sdfc_client *c, uint8_t type, const void *payload, size_t len, uint8_t reply,
                pending **out);
static int decode_hello(sdfc_client *c, pending *p, sdfc_hello_info *out);

/* AUTH with the kept token and HELLO on a new connection, before anything else. */
static int handshake(sdfc_client *c)
{
    pending *p;
    int rc = 0;
    if (c->token && !(rc = call(c, SDF_PROTO_AUTH, c->token, c->token_len, SDF_PROTO_AUTH_OK, &p)))
        claim(c, p);
    if (rc)
        return rc == SDFC_ESERVER ? SDFC_ECLOSED : rc; /* the server closes after a refusal */
    static const char name[] = "libsdfclient";
    if ((rc = call(c, SDF_PROTO_HELLO, name, sizeof name - 1, SDF_PROTO_HELLO_OK, &p)))
        return rc == SDFC_ESERVER ? SDFC_EPROTO : rc;
    sdfc_hello_info h;
    return decode_hello(c, p, &h);
}

static int reconnect(sdfc_client *c)
{
    c->reconnecting = 1;
    sdfc__conn_close(&c->conn);
    free(c->rx.buf);
    c->rx = (reader){0};
    c->generation++;
    int rc = sdfc__conn_open(&c->conn, c->host, c->port, c->tls, c->connect_timeout_ms);
    if (!rc) {
        c->stats.connects++;
        rc = handshake(c);
    }
    /* the table does not move while sending: only new requests are added to it */
    for (size_t i = 0; !rc && i < c->n; i++) {
        pending *p = &c->pend[c->head + i];
        if (p->state != IN_FLIGHT)
            continue;
        p->resent = 1;
        c->stats.resent++;
        struct iovec iov[2] = {{p->frame, p->frame_len}, {(void *)p->points, p->points_len}};
        rc = tx(c, iov, p->points_len ? 2 : 1);
    }
    c->reconnecting = 0;
    return rc ? set_broken(c, rc) : 0;
}

/* The connection closed or was reset: replace it if every request in flight may go again
 * (sdfclient.h), else the handle is broken with `code`. 0 once replaced. */
static int conn_lost(sdfc_client *c, int code)
{
    int again = c->resend && !c->reconnecting && !c->broken;
    for (size_t i = 0; again && i < c->n; i++) {
        pending *p = &c->pend[c->head + i];
        if (p->state == IN_FLIGHT && (!p->frame || p->resent))
            again = 0;
    }
    return again ? reconnect(c) : set_broken(c, code);
}

/* ---- waiting ----------------------------------------------------------------------------- */

int sdfc_wait(sdfc_client *c, uint32_t request_id)
{
    int rc = begin(c);
    if (rc)
        return rc;
    pending *p = lookup(c, request_id);
    if (!p)
        return SDFC_ENOREQUEST;
    while (p->state != DONE) {
        if ((rc = rx_one(c)))
            return rc;
        p = lookup(c, request_id); /* the table may have moved */
    }
    return claim(c, p);
}

int sdfc_wait_any(sdfc_client *c, uint32_t *request_id)
{
    int rc = begin(c);
    if (rc || !request_id)
        return rc ? rc : SDFC_EINVAL;
    if (c->in_flight == 0)
        return SDFC_ENOREQUEST;
    for (;;) {
        pending *best = NULL;
        for (size_t i = 0; i < c->n; i++) {
            pending *p = &c->pend[c->head + i];
            if (p->state == DONE && (!best || p->done_seq < best->done_seq))
                best = p;
        }
        if (best) {
            *request_id = c->base_id + (uint32_t)(best - (c->pend + c->head));
            return claim(c, best);
        }
        if ((rc = rx_one(c)))
            return rc;
    }
}

/* Send a frame with no points that the server answers with `reply`; wait for it. On 0 the
 * entry is DONE with its payload, for the caller to read and then claim. All but AUTH may
 * be re-sent, their payload read again from `payload`, which outlives the entry. */
static int call(sdfc_client *c, uint8_t type, const void *payload, size_t len, uint8_t reply,
                pending **out)
{
    uint32_t id;
    pending *p = add_entry(c, &id);
    if (!p)
        return c->next_id == UINT32_MAX ? SDFC_ELIMIT : SDFC_ENOMEM;
    p->reply_type = reply;
    unsigned char head[SDF_PROTO_HEADER_SIZE];
    sdf_proto_encode_header(head, type, id, (uint32_t)len);
    struct iovec iov[2] = {{head, sizeof head}, {(void *)payload, len}};
    int rc = c->resend && type != SDF_PROTO_AUTH ? keep_frame(p, head, sizeof head, payload, len) : 0;
    if (!rc)
        rc = tx(c, iov, len ? 2 : 1);
    if (rc) {
        drop(c, lookup(c, id));
        return rc;
    }
    while ((p = lookup(c, id))->state != DONE)
        if ((rc = rx_one(c)))
            return rc;
    if (p->status)
        return claim(c, p);
    *out = p;
    return 0;
}

/* ---- HELLO, AUTH, LIST_MESHES ------------------------------------------------------------ */

int sdfc_hello(sdfc_client *c, sdfc_hello_info *out)
{
    int rc = begin(c);
    if (rc || !out)
        return rc ? rc : SDFC_EINVAL;
    static const char name[] = "libsdfclient";
    pending *p;
    if ((rc = call(c, SDF_PROTO_HELLO, name, sizeof name - 1, SDF_PROTO_HELLO_OK, &p)))
        return rc;
    return decode_hello(c, p, out);
}

/* A HELLO_OK into *out and the handle's limits; claims p. */
static int decode_hello(sdfc_client *c, pending *p, sdfc_hello_info *out)
{
    sdf_proto_hello h;
    const char *why;
    if (sdf_proto_decode_hello_ok(p->payload, p->payload_len, &h, &why)) {
        claim(c, p);
        return set_broken(c, SDFC_EPROTO);
    }
    out->version = h.version;
    out->max_payload = c->max_payload = h.max_payload;
    out->max_points = c->max_points = h.max_points;
    copy_str(out->server, sizeof out->server, h.server, h.server_len);
    return claim(c, p);
}

int sdfc_auth(sdfc_client *c, const char *token, size_t len)
{
    int rc = begin(c);
    if (rc || (!token && len))
        return rc ? rc : SDFC_EINVAL;
    pending *p;
    rc = call(c, SDF_PROTO_AUTH, token, len, SDF_PROTO_AUTH_OK, &p);
    if (rc == SDFC_ESERVER)
        set_broken(c, SDFC_ECLOSED); /* the server closes after a wrong token */
    if (rc)
        return rc;
    char *kept = malloc(len ? len : 1); /* for the connections that replace this one */
    if (!kept) {
        claim(c, p);
        return set_broken(c, SDFC_ENOMEM);
    }
    if (len)
        memcpy(kept, token, len);
    free(c->token);
    c->token = kept;
    c->token_len = len;
    return claim(c, p);
}

int sdfc_list_meshes(sdfc_client *c, sdfc_mesh *out, size_t cap, size_t *count)
{
    int rc = begin(c);
    if (rc || !count || (cap && !out))
        return rc ? rc : SDFC_EINVAL;
    pending *p;
    if ((rc = call(c, SDF_PROTO_LIST_MESHES, NULL, 0, SDF_PROTO_MESHES, &p)))
        return rc;
    uint32_t n;
    size_t off = 0;
    const char *why;
    rc = sdf_proto_meshes_count(p->payload, p->payload_len, &n);
    for (uint32_t i = 0; !rc && i < n; i++) {
        sdf_proto_mesh_entry e;
        if ((rc = sdf_proto_meshes_next(p->payload, p->payload_len, &off, &e, &why)))
            break;
        if (e.name_len > SDF_PROTO_MAX_NAME) {
            rc = SDFC_EPROTO;
        } else if (i < cap) {
            out[i] = (sdfc_mesh){.triangles = e.triangles, .closed = e.closed,
                                 .auto_sign = e.auto_sign};
            copy_str(out[i].name, sizeof out[i].name, e.name, e.name_len);
        }
    }
    if (!rc && (n ? off : 4) != p->payload_len)
        rc = SDFC_EPROTO;
    claim(c, p);
    if (rc)
        return set_broken(c, SDFC_EPROTO);
    *count = n;
    return 0;
}

/* ---- queries ----------------------------------------------------------------------------- */

static int to_filter(const sdfc_filter *in, sdf_proto_query *q)
{
    sdfc_filter f = in ? *in : (sdfc_filter){0};
    unsigned known = SDFC_FILTER_GRID | SDFC_FILTER_UNSIGNED | SDFC_FILTER_WIDE_BUMP |
                     SDFC_FILTER_SAMPLE_GRADIENT;
    if ((f.flags & ~known) || f.kernel < 0 || f.kernel > 255 || f.smooth < 0 ||
        f.smooth > SDFC_SMOOTH_MESH)
        return SDFC_EINVAL;
    sdf_filter_options *o = &q->filter;
    o->kernel = (sdf_kernel)f.kernel;
    o->grid = !!(f.flags & SDFC_FILTER_GRID);
    o->unsigned_integrand = !!(f.flags & SDFC_FILTER_UNSIGNED);
    o->allow_wide_bump = !!(f.flags & SDFC_FILTER_WIDE_BUMP);
    o->sample_gradient = !!(f.flags & SDFC_FILTER_SAMPLE_GRADIENT);
    /* values past int go out as INT_MAX, which the server refuses with its bound */
    o->samples = f.samples > INT_MAX ? INT_MAX : (int)f.samples;
    o->min_samples = f.min_samples > INT_MAX ? INT_MAX : (int)f.min_samples;
    o->cap = f.cap;
    o->a = f.a;
    o->b = f.b;
    o->medial = f.medial;
    o->seed = f.seed;
    o->smooth.shape = (sdf_volume_shape)f.smooth;
    o->smooth.depth = f.depth;
    o->smooth.scale = f.scale;
    if (f.smooth == SDFC_SMOOTH_SPHERE) {
        memcpy(o->smooth.center, f.shape, sizeof o->smooth.center);
        o->smooth.radius = f.shape[3];
    } else if (f.smooth == SDFC_SMOOTH_BOX) {
        memcpy(o->smooth.lo, f.shape, sizeof o->smooth.lo);
        memcpy(o->smooth.hi, f.shape + 3, sizeof o->smooth.hi);
    } else if (f.smooth == SDFC_SMOOTH_MESH) {
        if (!f.smooth_mesh)
            return SDFC_EINVAL;
        q->volume_name = f.smooth_mesh;
        q->volume_name_len = strlen(f.smooth_mesh);
    }
    return 0;
}

/* Checks common to both query kinds, before anything is sent. */
static int check_query(sdfc_client *c, const char *name, const float *points, uint32_t count,
                       const void *result, size_t result_size, size_t need, uint32_t *id)
{
    int rc = begin(c);
    if (rc)
        return rc;
    if (!name || !id || (count && (!points || !result)))
        return SDFC_EINVAL;
    size_t len = strlen(name);
    if (len == 0 || len > SDF_PROTO_MAX_NAME)
        return SDFC_EINVAL;
    if (result_size < need || (c->max_points && count > c->max_points))
        return SDFC_ELIMIT;
    return 0;
}

/* Register the request and send `frame` (header and prefix, its length and count fields
 * still to set) followed by the points, straight from the caller's array. */
static int send_points(sdfc_client *c, unsigned char *frame, size_t frame_len, size_t payload,
                       uint8_t mode, const float *points, uint32_t count, void *result,
                       size_t need, uint32_t *request_id)
{
    if (payload > UINT32_MAX || (c->max_payload && payload > c->max_payload))
        return SDFC_ELIMIT;
    uint32_t id;
    pending *p = add_entry(c, &id);
    if (!p)
        return c->next_id == UINT32_MAX ? SDFC_ELIMIT : SDFC_ENOMEM;
    p->reply_type = SDF_PROTO_RESULT;
    p->result = result;
    p->expect = need;
    sdf_proto_encode_result_head(p->head, id, (sdf_proto_mode)mode, count);
    put32(frame + 8, id);
    put32(frame + 12, (uint32_t)payload);
    put32(frame + SDF_PROTO_HEADER_SIZE + 4, count);
    struct iovec iov[2] = {{frame, frame_len}, {(void *)points, 12 * (size_t)count}};
    int rc = c->resend ? keep_frame(p, frame, frame_len, points, 12 * (size_t)count) : 0;
    if (!rc)
        rc = tx(c, iov, count ? 2 : 1);
    if (rc) {
        drop(c, lookup(c, id));
        return rc;
    }
    *request_id = id;
    return 0;
}

/* Header and prefix room: 16 + 8 + 256 (name) + 120 (FILTER) + 256 (its mesh name). */
#define PREFIX_MAX 664

/* The codec copies zero points from here when it writes a frame's prefix (memcpy wants a
 * valid pointer even for no bytes). */
static const float no_points[3];

int sdfc_send_query(sdfc_client *c, const char *mesh, sdfc_mode mode, sdfc_sign sign,
                    const sdfc_filter *filter, const float *points, uint32_t count,
                    void *result, size_t result_size, uint32_t *request_id)
{
    if ((unsigned)mode > SDF_MODE_LAST || (unsigned)sign > SDF_SIGN_NONE)
        return c && c->broken ? c->broken : SDFC_EINVAL;
    int rc = check_query(c, mesh, points, count, result, result_size,
                         sdfc_result_size(mode, count), request_id);
    if (rc)
        return rc;
    sdf_proto_query q = {.mode = (sdf_proto_mode)mode, .sign = (sdf_sign_method)sign,
                         .name = mesh, .name_len = strlen(mesh), .count = 0,
                         .points = no_points};
    if (sdf_proto_mode_filtered(q.mode) && (rc = to_filter(filter, &q)))
        return rc;
    /* the codec writes the frame for zero points; its length and count are set later */
    unsigned char frame[PREFIX_MAX];
    size_t frame_len = sdf_proto_encode_query(frame, sizeof frame, 0, &q);
    if (!frame_len)
        return SDFC_EINVAL;
    q.count = count;
    return send_points(c, frame, frame_len, sdf_proto_query_size(&q), (uint8_t)mode, points,
                       count, result, sdfc_result_size(mode, count), request_id);
}

int sdfc_send_volume_query(sdfc_client *c, const char *volume, int gradient,
                           sdfc_interpolation interpolation, const float *points,
                           uint32_t count, void *result, size_t result_size,
                           uint32_t *request_id)
{
    /* the codec's terms for the wire codes (sdfc_interpolation's values) */
    static const sdf_volume_filter filters[] = {SDF_VOLUME_TRILINEAR, SDF_VOLUME_NEAREST,
                                                SDF_VOLUME_HERMITE, SDF_VOLUME_DEFAULT};
    sdfc_mode mode = gradient ? SDFC_GRADIENT : SDFC_SIGNED;
    if ((unsigned)interpolation >= sizeof filters / sizeof filters[0])
        return SDFC_EINVAL;
    int rc = check_query(c, volume, points, count, result, result_size,
                         sdfc_result_size(mode, count), request_id);
    if (rc)
        return rc;
    sdf_proto_volume_query q = {.gradient = !!gradient,
                                .interpolation = filters[interpolation],
                                .name = volume, .name_len = strlen(volume), .count = 0,
                                .points = no_points};
    unsigned char frame[PREFIX_MAX];
    size_t frame_len = sdf_proto_encode_volume_query(frame, sizeof frame, 0, &q);
    if (!frame_len)
        return SDFC_EINVAL;
    q.count = count;
    return send_points(c, frame, frame_len, sdf_proto_volume_query_size(&q), (uint8_t)mode,
                       points, count, result, sdfc_result_size(mode, count), request_id);
}

int sdfc_query(sdfc_client *c, const char *mesh, sdfc_mode mode, sdfc_sign sign,
               const sdfc_filter *filter, const float *points, uint32_t count, void *result,
               size_t result_size)
{
    uint32_t id;
    int rc = sdfc_send_query(c, mesh, mode, sign, filter, points, count, result, result_size, &id);
    return rc ? rc : sdfc_wait(c, id);
}
