/* pipeline.c - libsdfclient's requests in flight on one non-blocking connection to sdfd's
 * binary port (transport.c: TCP, or TLS over it), framed with proto/'s codec. Replies are
 * read by a small state machine (header, then a RESULT's 8-byte prefix and its words straight
 * into the caller's buffer, or any other frame into a bounded heap block), so a reply never
 * needs a copy and a send that finds the socket full can read replies meanwhile: a client
 * that sends far more requests than the server keeps in flight (64) then never deadlocks
 * with it.
 *
 * Re-sending (sdfclient.h): a re-sendable request keeps a copy of its frame's header and
 * prefix and a pointer to the caller's points. When the connection is lost, reconnect()
 * replaces it in place (the table stays; the reader starts afresh) and sends every
 * unanswered request again. It may run deep inside a send that was itself interrupted: the
 * connection's generation tells that send its frame already went out whole on the new one. */
#include "pipeline.h"

#include <errno.h>
#include <limits.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* A reply other than a RESULT (HELLO_OK, MESHES, ERROR, AUTH_OK) is read into the heap: at
 * most this many bytes, about 200,000 mesh names. */
#define CTRL_MAX_PAYLOAD ((uint32_t)64 << 20)

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

int sdfc__set_broken(sdfc_client *c, int code)
{
    if (!c->broken)
        c->broken = code;
    return c->broken;
}

void sdfc__free_entry(sdfc__pending *p)
{
    free(p->payload);
    free(p->err);
    free(p->frame);
    *p = (sdfc__pending){0};
}

/* ---- the table of requests in flight ----------------------------------------------------- */

sdfc__pending *sdfc__lookup(sdfc_client *c, uint32_t id)
{
    uint32_t i = id - c->base_id;
    if (id == 0 || i >= c->n)
        return NULL;
    sdfc__pending *p = &c->pend[c->head + i];
    return p->state == SDFC__FREE ? NULL : p;
}

/* A new entry for the next id; NULL when out of memory or ids. */
sdfc__pending *sdfc__add_entry(sdfc_client *c, uint32_t *id)
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
            sdfc__pending *grown = realloc(c->pend, cap * sizeof *grown);
            if (!grown)
                return NULL;
            c->pend = grown;
            c->cap = cap;
        }
    }
    if (c->n == 0)
        c->base_id = c->next_id;
    sdfc__pending *p = &c->pend[c->head + c->n++];
    *p = (sdfc__pending){.state = SDFC__IN_FLIGHT};
    *id = c->next_id++;
    c->in_flight++;
    return p;
}

/* Hand a finished entry back: its error (if any) becomes the handle's; the table's head
 * moves past entries already given back. */
int sdfc__claim(sdfc_client *c, sdfc__pending *p)
{
    int status = p->status;
    if (p->err)
        c->err = *p->err;
    sdfc__free_entry(p);
    c->in_flight--;
    while (c->n > 0 && c->pend[c->head].state == SDFC__FREE) {
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
void sdfc__drop(sdfc_client *c, sdfc__pending *p) { (void)sdfc__claim(c, p); }

/* ---- reading replies --------------------------------------------------------------------- */

void sdfc__copy_str(char *dst, size_t cap, const char *s, size_t len)
{
    if (len >= cap)
        len = cap - 1;
    memcpy(dst, s, len);
    dst[len] = 0;
}

static int rx_route(sdfc_client *c)
{
    sdfc__reader *r = &c->rx;
    const char *why;
    if (sdf_proto_decode_header(r->hdr, SDF_PROTO_HEADER_SIZE, UINT32_MAX, &r->h, &why))
        return sdfc__set_broken(c, SDFC_EPROTO);
    r->routed = 1;
    sdfc__pending *p = sdfc__lookup(c, r->h.request_id);
    if (p && p->state != SDFC__IN_FLIGHT)
        return sdfc__set_broken(c, SDFC_EPROTO); /* a second reply to one request */
    if (!p && !(r->h.request_id == 0 && r->h.type == SDF_PROTO_ERROR))
        return sdfc__set_broken(c, SDFC_EPROTO); /* a reply to nothing we asked */
    if (r->h.type == SDF_PROTO_RESULT) {
        if (p->reply_type != SDF_PROTO_RESULT || r->h.length != SDF_PROTO_RESULT_PREFIX + p->expect)
            return sdfc__set_broken(c, SDFC_EPROTO);
        return 0;
    }
    if (r->h.type != SDF_PROTO_ERROR && (!p || r->h.type != p->reply_type))
        return sdfc__set_broken(c, SDFC_EPROTO);
    if (r->h.length > CTRL_MAX_PAYLOAD)
        return sdfc__set_broken(c, SDFC_ELIMIT);
    r->buf = malloc(r->h.length ? r->h.length : 1);
    return r->buf ? 0 : sdfc__set_broken(c, SDFC_ENOMEM);
}

static int store_error(sdfc_client *c, sdfc_server_err *dst)
{
    sdfc__reader *r = &c->rx;
    sdf_proto_error e;
    const char *why;
    if (sdf_proto_decode_error(r->buf, r->h.length, &e, &why))
        return sdfc__set_broken(c, SDFC_EPROTO);
    dst->status = e.status;
    sdfc__copy_str(dst->code, sizeof dst->code, e.code, e.code_len);
    sdfc__copy_str(dst->message, sizeof dst->message, e.message, e.message_len);
    return 0;
}

/* A query the server refused as unavailable (503 EUNAVAILABLE: a replica shutting down, or
 * still loading) that may go again on a new connection: re-sending is on, and it has not
 * gone again yet (sdfclient.h, "Re-sending"). */
static int may_move(const sdfc_client *c, const sdfc__pending *p, const sdfc_server_err *e)
{
    return c->resend && p->frame && !p->resent && p->reply_type == SDF_PROTO_RESULT &&
           e->status == 503 && !strcmp(e->code, "EUNAVAILABLE");
}

/* An ERROR frame, in full: about the connection, a refusal of p (*answered set), or p's to
 * go again on the next connection. */
static int file_error(sdfc_client *c, sdfc__pending *p, int *answered)
{
    sdfc_server_err e;
    int rc = store_error(c, p ? &e : &c->err);
    if (rc)
        return rc;
    if (!p) /* about the connection, which the server now closes */
        return sdfc__set_broken(c, SDFC_ECLOSED);
    if (may_move(c, p, &e)) {
        p->unavailable = 1; /* stays in flight until it went again */
        c->unavailable++;
        return 0;
    }
    if (!(p->err = malloc(sizeof *p->err)))
        return sdfc__set_broken(c, SDFC_ENOMEM);
    *p->err = e;
    p->status = SDFC_ESERVER;
    *answered = 1;
    return 0;
}

/* The current frame is in full: file it with its request. */
static int rx_finish(sdfc_client *c)
{
    sdfc__reader *r = &c->rx;
    sdfc__pending *p = sdfc__lookup(c, r->h.request_id);
    int rc = 0, answered = 1;
    if (r->h.type == SDF_PROTO_RESULT) {
        /* header bytes but the flags (receivers ignore them), then the prefix */
        if (memcmp(r->hdr, p->head, 6) || memcmp(r->hdr + 8, p->head + 8, 16))
            rc = sdfc__set_broken(c, SDFC_EPROTO);
    } else if (r->h.type == SDF_PROTO_ERROR) {
        answered = 0;
        rc = file_error(c, p, &answered);
    } else {
        p->payload = r->buf;
        p->payload_len = r->h.length;
        r->buf = NULL;
    }
    free(r->buf);
    r->buf = NULL;
    r->got = 0;
    r->routed = 0;
    if (p && !rc && answered) {
        p->state = SDFC__DONE;
        p->done_seq = ++c->done_seq;
    }
    return rc;
}

/* Where the next bytes of the current frame go, and how many are wanted. */
static unsigned char *rx_target(sdfc_client *c, size_t *want)
{
    sdfc__reader *r = &c->rx;
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
        sdfc__pending *p = sdfc__lookup(c, r->h.request_id);
        *want = p->expect - at;
        return p->result + at;
    }
    *want = r->h.length - at;
    return r->buf + at;
}

static int conn_lost(sdfc_client *c, int code);
static int reconnect(sdfc_client *c);
static int should_move(const sdfc_client *c);

/* A failed send or receive (errno) as the handle's error; a peer that went away may have
 * its connection replaced. */
static int io_failed(sdfc_client *c, int err)
{
    if (err == ECONNRESET || err == EPIPE)
        return conn_lost(c, SDFC_ECLOSED);
    return sdfc__set_broken(c, err == EPROTO ? SDFC_ETLS : SDFC_EIO);
}

/* Read what the connection holds without blocking; *frames counts the frames completed. */
static int rx_pump(sdfc_client *c, int *frames)
{
    sdfc__reader *r = &c->rx;
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
            return sdfc__set_broken(c, SDFC_ETIMEDOUT);
        left = l > INT_MAX ? INT_MAX : (int)l + 1;
    }
    return sdfc__conn_wait(&c->conn, events, left) < 0 ? sdfc__set_broken(c, SDFC_EIO) : 0;
}


/* Block until at least one more frame completes, or the reply timeout passes. */
int sdfc__rx_one(sdfc_client *c)
{
    int moved = should_move(c) ? reconnect(c) : 0;
    if (moved)
        return moved;
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
int sdfc__tx(sdfc_client *c, struct iovec *iov, int iovcnt)
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
int sdfc__keep_frame(sdfc__pending *p, const void *frame, size_t len, const void *points,
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

/* AUTH with the kept token and, with `hello`, HELLO on a new connection, before anything
 * else. A refused AUTH is SDFC_ESERVER (the server closes the connection after it). */
static int handshake(sdfc_client *c, int hello)
{
    sdfc__pending *p;
    int rc = 0;
    if (c->token && !(rc = sdfc__call(c, SDF_PROTO_AUTH, c->token, c->token_len, SDF_PROTO_AUTH_OK, &p)))
        sdfc__claim(c, p);
    if (rc || !hello)
        return rc;
    static const char name[] = "libsdfclient";
    if ((rc = sdfc__call(c, SDF_PROTO_HELLO, name, sizeof name - 1, SDF_PROTO_HELLO_OK, &p)))
        return rc == SDFC_ESERVER ? SDFC_EPROTO : rc;
    sdfc_hello_info h;
    return sdfc__decode_hello(c, p, &h);
}

/* A new connection's failure was its loss before the handshake's reply: closed or reset,
 * as a balancer does when it hands the connection to a replica that is going away (with
 * TLS, during the TLS handshake too). Another connection may well not meet it. */
static int lost_early(const sdfc_client *c, int rc)
{
    return !c->broken && (rc == SDFC_ECLOSED || (rc == SDFC_ETLS && c->conn.gone));
}

static void nap(long ms)
{
    struct timespec ts = {.tv_sec = ms / 1000, .tv_nsec = ms % 1000 * 1000000L};
    while (nanosleep(&ts, &ts) && errno == EINTR)
        ;
}

int sdfc__open(sdfc_client *c, int hello)
{
    int attempts = c->resend ? SDFC__CONNECT_ATTEMPTS : 1, rc = 0;
    c->opening = 1;
    for (int i = 0; i < attempts; i++) {
        if (i)
            nap(50L << (i - 1));
        sdfc__conn_close(&c->conn);
        free(c->rx.buf);
        c->rx = (sdfc__reader){0};
        c->generation++;
        rc = sdfc__conn_open(&c->conn, c->host, c->port, c->tls, c->connect_timeout_ms);
        if (!rc) {
            c->stats.connects++;
            rc = handshake(c, hello);
        }
        if (!rc || !lost_early(c, rc))
            break;
    }
    c->opening = 0;
    return rc;
}

/* A new connection in place of the current one, and every request in flight sent again on
 * it. 0, or the handle broken. */
static int reconnect(sdfc_client *c)
{
    c->reconnecting = 1;
    int rc = sdfc__open(c, 1);
    if (rc == SDFC_ESERVER)
        rc = SDFC_ECLOSED; /* a refused AUTH, after which the server closes */
    /* the table does not move while sending: only new requests are added to it */
    for (size_t i = 0; !rc && i < c->n; i++) {
        sdfc__pending *p = &c->pend[c->head + i];
        if (p->state != SDFC__IN_FLIGHT)
            continue;
        p->resent = 1;
        p->unavailable = 0;
        c->stats.resent++;
        struct iovec iov[2] = {{p->frame, p->frame_len}, {(void *)p->points, p->points_len}};
        rc = sdfc__tx(c, iov, p->points_len ? 2 : 1);
    }
    c->unavailable = 0;
    c->reconnecting = 0;
    return rc ? sdfc__set_broken(c, rc) : 0;
}

/* The connection closed or was reset: replace it if every request in flight may go again
 * (sdfclient.h), else the handle is broken with `code`. 0 once replaced. A new connection
 * lost during its handshake is sdfc__open's to try again. */
static int conn_lost(sdfc_client *c, int code)
{
    if (c->opening)
        return code;
    int again = c->resend && !c->reconnecting && !c->broken;
    for (size_t i = 0; again && i < c->n; i++) {
        sdfc__pending *p = &c->pend[c->head + i];
        if (p->state == SDFC__IN_FLIGHT && (!p->frame || p->resent))
            again = 0;
    }
    return again ? reconnect(c) : sdfc__set_broken(c, code);
}

/* Every request still in flight was refused as unavailable: no reply this connection may
 * still bring is worth waiting for, so they go again on a new one. */
static int should_move(const sdfc_client *c)
{
    if (!c->unavailable || c->reconnecting || c->opening || c->broken)
        return 0;
    for (size_t i = 0; i < c->n; i++) {
        const sdfc__pending *p = &c->pend[c->head + i];
        if (p->state == SDFC__IN_FLIGHT && !p->unavailable)
            return 0;
    }
    return 1;
}

/* Send a frame with no points that the server answers with `reply`; wait for it. On 0 the
 * entry is SDFC__DONE with its payload, for the caller to read and then claim. All but AUTH may
 * be re-sent, their payload read again from `payload`, which outlives the entry. */
int sdfc__call(sdfc_client *c, uint8_t type, const void *payload, size_t len, uint8_t reply,
                sdfc__pending **out)
{
    uint32_t id;
    sdfc__pending *p = sdfc__add_entry(c, &id);
    if (!p)
        return c->next_id == UINT32_MAX ? SDFC_ELIMIT : SDFC_ENOMEM;
    p->reply_type = reply;
    unsigned char head[SDF_PROTO_HEADER_SIZE];
    sdf_proto_encode_header(head, type, id, (uint32_t)len);
    struct iovec iov[2] = {{head, sizeof head}, {(void *)payload, len}};
    int rc = c->resend && type != SDF_PROTO_AUTH ? sdfc__keep_frame(p, head, sizeof head, payload, len) : 0;
    if (!rc)
        rc = sdfc__tx(c, iov, len ? 2 : 1);
    if (rc) {
        sdfc__drop(c, sdfc__lookup(c, id));
        return rc;
    }
    while ((p = sdfc__lookup(c, id))->state != SDFC__DONE) {
        if ((rc = sdfc__rx_one(c))) {
            if ((p = sdfc__lookup(c, id))) /* a handshake's entry: sdfc__open may try again */
                sdfc__drop(c, p);
            return rc;
        }
    }
    if (p->status)
        return sdfc__claim(c, p);
    *out = p;
    return 0;
}

/* A HELLO_OK into *out and the handle's limits; claims p. */
int sdfc__decode_hello(sdfc_client *c, sdfc__pending *p, sdfc_hello_info *out)
{
    sdf_proto_hello h;
    const char *why;
    if (sdf_proto_decode_hello_ok(p->payload, p->payload_len, &h, &why)) {
        sdfc__claim(c, p);
        return sdfc__set_broken(c, SDFC_EPROTO);
    }
    out->version = h.version;
    out->max_payload = c->max_payload = h.max_payload;
    out->max_points = c->max_points = h.max_points;
    sdfc__copy_str(out->server, sizeof out->server, h.server, h.server_len);
    return sdfc__claim(c, p);
}
