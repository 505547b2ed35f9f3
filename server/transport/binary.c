/* binary.c - the binary protocol listener: one thread watches the listening socket and every
 * connection (non-blocking) with epoll and splits the byte stream into frames, which
 * sdfd_bin_handle_frame (binrequests.c) answers or hands on; replies finished on other
 * threads are appended to the connection's output queue (binconn.c), the connection is put on
 * a list for the loop (sdfd_bin_request_finished) and the loop is woken through an eventfd.
 * Replies therefore leave in completion order, matched by request id.
 *
 * A pass of the loop costs what its ready connections cost, not what the open ones do, so a
 * crowd of idle connections does not slow the others down: it looks at the connections epoll
 * reports, those on the list of finished requests, and those on its own ready list (below),
 * and only once a second at every connection, for the clocks of the limits below. epoll is
 * level-triggered: the loop reads a connection at most once a pass (one slow-to-drain client
 * cannot hold the others up), it stops reading one by taking EPOLLIN out of its interest, and
 * an event it did not act on comes back on the next pass, where edge triggering would need a
 * list of its own for every connection with bytes left unread, and lose the connection for
 * good if one were missed. Each connection's interest is changed (epoll_ctl) only when what it
 * waits on changes.
 *
 * Limits: a frame's length is checked against max_payload before the input buffer grows;
 * at most 64 queries per connection are in flight and at most 64 MiB of replies wait unsent,
 * beyond which the connection is not read (TCP backpressure on a client that does not
 * read; it is read again when a request ends or replies go out); a connection is closed when
 * its replies have not moved for the timeout (a client that does not read), when it is idle
 * mid-frame for the timeout, and when a frame (the first one from the connection's start, the
 * next ones from their first byte) takes longer than the timeout plus a second per MIN_RATE
 * bytes (a client that trickles bytes, or connects and never sends); idle between frames it
 * stays open. Those clocks are checked once a second, so a cut comes up to a second late. A
 * framing error gets one ERROR frame and the connection closes after it is sent; a frame
 * with no room under --max-buffered-bytes gets an ERROR and is read and dropped, and the
 * connection goes on. A connection that goes away with queries in flight is freed when the
 * last of them completes.
 *
 * With --bin-tls every connection is a GnuTLS session on the same non-blocking socket
 * (binconn.c's I/O): the handshake is taken a step at a time as epoll says the socket is
 * ready for what GnuTLS waits on, and a connection whose handshake has not ended --timeout
 * after it was accepted is closed, so a client that stops halfway holds a slot no longer
 * than an idle one. Records GnuTLS has decrypted but not yet handed over do not show in
 * epoll: such a connection goes on the ready list and is read on the next pass without
 * waiting. So does one whose input holds a whole frame the limits held back once they let it
 * go. The limits above apply unchanged to the decrypted bytes.
 *
 * Shutdown (SIGTERM) sheds the clients so that they reconnect elsewhere (behind a balancer,
 * to another replica): from the moment the server drains no new frame is handed on; the
 * quiesce shuts the listening socket (connects are refused at once, and those waiting in its
 * backlog reset), and every connection is closed as soon as it has no query in flight and
 * nothing unsent: its replies go out first, and one idle between frames closes at once.
 * Frames it had not handed on (held back by the limits, or sent after the drain began) are
 * not answered: the client sees its connection end and sends them again on a new one. The
 * 503 EUNAVAILABLE binrequests.c answers for a draining server is left to a frame handed on
 * in the instant the drain begins (it passed this file's check, then saw the flag); its main
 * use is a server still loading its meshes. */
#define _GNU_SOURCE /* accept4 */
#include "transport/binary.h"

#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <netinet/in.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include "core/errors.h"
#include "core/log.h"
#include "proto.h"
#include "transport/binconn.h"
#include "transport/binrequests.h"
#include "transport/net.h"

#define MAX_IN_FLIGHT 64
#define INPUT_BASE (64 * 1024) /* a connection's input buffer between big frames */
#define MAX_QUEUED_OUT (64u << 20) /* unsent reply bytes before we stop reading */
#define MIN_RATE (64.0 * 1024) /* bytes a second a frame must arrive at, after the timeout */
#define MAX_EVENTS 256 /* epoll events taken a pass; more wait for the next one */
#define DISCARD_MAX (64 * 1024) /* unread bytes dropped before a close, so it sends no reset */

/* ---- connections ------------------------------------------------------------------------- */

static int resize_input(sdfd_binary *b, connection *c, size_t cap);

/* Parse every complete frame in the input buffer; none once the server drains (the file's
 * comment). */
static void consume_input(sdfd_binary *b, connection *c)
{
    size_t off = 0;
    while (!c->closing && !atomic_load(&b->srv->draining) &&
           c->in_len - off >= SDF_PROTO_HEADER_SIZE) {
        pthread_mutex_lock(&c->lock);
        int busy = c->in_flight >= MAX_IN_FLIGHT || c->out_bytes >= MAX_QUEUED_OUT;
        pthread_mutex_unlock(&c->lock);
        if (busy)
            break; /* the rest waits for replies to go out */
        sdf_proto_header h;
        const char *why;
        int rc = sdf_proto_decode_header(c->in + off, c->in_len - off, b->max_payload, &h, &why);
        if (rc) { /* the stream cannot be trusted any more */
            sdfd_bin_send_error(c, 0, rc, why);
            c->closing = 1;
            break;
        }
        if (c->in_len - off - SDF_PROTO_HEADER_SIZE < h.length)
            break; /* the rest of this frame has not arrived */
        sdfd_bin_handle_frame(b, c, &h, c->in + off + SDF_PROTO_HEADER_SIZE);
        off += SDF_PROTO_HEADER_SIZE + h.length;
    }
    if (off) { /* c->in is NULL before the first read */
        memmove(c->in, c->in + off, c->in_len - off);
        c->in_len -= off;
        c->in_since = c->in_len ? sdfd_now() : 0; /* the next frame's clock */
        c->in_got = c->in_len;
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

/* Too many bytes held over all connections (or no memory) for the input buffer. Past a
 * frame's header (every byte after it is that frame's) the frame is refused, and the rest
 * of it read and dropped as it arrives, so the connection goes on with the next frame and
 * the client reads its ERROR. Before one (a new connection's first buffer) there is no
 * frame to skip: the connection gets the ERROR (request id 0) and is closed, what it has
 * sent so far read and dropped first, as closing on unread bytes would reset the
 * connection and could lose the ERROR. */
static void refuse_for_room(sdfd_binary *b, connection *c)
{
    char why[160];
    snprintf(why, sizeof why, SDFD_BUFFER_BUSY_FMT, b->srv->cfg.max_buffered_bytes);
    sdf_proto_header h;
    if (c->in_len < SDF_PROTO_HEADER_SIZE ||
        sdf_proto_decode_header(c->in, c->in_len, b->max_payload, &h, NULL)) {
        unsigned char sink[4096];
        for (int reads = 0; reads < 16 && sdfd_bin_recv(c, sink, sizeof sink) > 0; reads++)
            ;
        sdfd_bin_send_error(c, 0, SDFD_EBUSY, why);
        c->closing = 1;
        return;
    }
    sdfd_bin_send_error(c, h.request_id, SDFD_EBUSY, why);
    size_t frame = SDF_PROTO_HEADER_SIZE + (size_t)h.length;
    const sdfd_op *op;
    const char *what;
    sdfd_bin_frame_kind(h.type, &op, &what);
    sdfd_bin_account(b, op, what, sdfd_http_status(SDFD_EBUSY), 0, sdfd_now(), frame, 0);
    c->skip = frame - c->in_len;
    c->in_len = 0;
}

static int read_input(sdfd_binary *b, connection *c)
{
    size_t need = input_need(b, c);
    if (!c->skip && need > c->in_cap && resize_input(b, c, need)) {
        refuse_for_room(b, c);
        return 0;
    }
    size_t room = c->skip ? (c->skip < c->in_cap ? c->skip : c->in_cap) : c->in_cap - c->in_len;
    ssize_t n = sdfd_bin_recv(c, c->in + c->in_len, room);
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR))
        return -1;
    if (n > 0) {
        c->last_activity = sdfd_now();
        if (!c->in_since)
            c->in_since = c->last_activity, c->in_got = 0;
        c->in_got += (size_t)n;
        if (c->skip) { /* a refused frame's bytes, dropped */
            c->skip -= (size_t)n;
            if (!c->skip && !c->in_len)
                c->in_since = 0;
            return 0;
        }
        c->in_len += (size_t)n;
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
        ssize_t n = sdfd_bin_send(c, f->data + f->sent, f->len - f->sent);
        if (n < 0)
            return errno == EAGAIN || errno == EINTR ? 0 : -1;
        c->last_activity = c->out_since = sdfd_now();
        f->sent += (size_t)n;
        if (f->sent < f->len)
            return 0;
        pthread_mutex_lock(&c->lock);
        c->out_head = f->next;
        if (!c->out_head)
            c->out_tail = NULL, c->out_since = 0;
        c->out_bytes -= f->len;
        pthread_mutex_unlock(&c->lock);
        free(f->data);
        free(f);
    }
}

/* Read and drop what the client sent and nobody will read (at most DISCARD_MAX): closing a
 * socket with unread bytes resets the connection, and the reset can cost the client the
 * replies it has not read yet. */
static void discard_unread(connection *c)
{
    unsigned char sink[4096];
    for (size_t n = 0; n < DISCARD_MAX;) {
        ssize_t got = sdfd_bin_recv(c, sink, sizeof sink);
        if (got <= 0)
            return;
        n += (size_t)got;
    }
}

/* Put closed connection c on the list reap() goes through at the end of the pass. */
static void reap_later(sdfd_binary *b, connection *c)
{
    if (!c->reaping) {
        c->reaping = 1;
        c->reap_next = b->reap;
        b->reap = c;
    }
}

/* Close the socket (which takes it out of the epoll set); the connection itself is freed at
 * the end of the pass if nothing refers to it any more (reap). */
static void close_socket(sdfd_binary *b, connection *c)
{
    sdfd_bin_end_tls(b, c);
    if (c->fd >= 0) {
        epoll_ctl(b->epoll_fd, EPOLL_CTL_DEL, c->fd, NULL);
        close(c->fd);
        c->fd = -1;
        b->conn_count--;
    }
    c->dead = 1;
    free(c->in); /* nothing reads it any more; its room goes back to the budget */
    c->in = NULL;
    sdfd_buffer_release(b->srv, c->in_cap);
    c->in_cap = c->in_len = 0;
    reap_later(b, c);
}

static void free_connection(sdfd_binary *b, connection *c)
{
    sdfd_bin_end_tls(b, c);
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

/* Watch connection c for `events` (level-triggered), if that is not what it is watched for. */
static void watch(sdfd_binary *b, connection *c, uint32_t events)
{
    if (events == c->watched)
        return;
    struct epoll_event ev = {.events = events, .data.ptr = c};
    if (!epoll_ctl(b->epoll_fd, EPOLL_CTL_MOD, c->fd, &ev))
        c->watched = events;
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
        c->last_activity = c->opened = c->in_since = sdfd_now(); /* its first frame's clock */
        c->handshaken = !b->srv->cfg.bin_tls;
        /* Plain or TLS, the client speaks first (a frame, a ClientHello). */
        struct epoll_event ev = {.events = EPOLLIN, .data.ptr = c};
        if ((!c->handshaken && sdfd_tls_session_begin(b->srv->tls, fd, &c->tls, &c->cert)) ||
            epoll_ctl(b->epoll_fd, EPOLL_CTL_ADD, fd, &ev)) {
            if (c->tls)
                sdfd_tls_session_end(b->srv->tls, c->tls, c->cert);
            close(fd);
            free(c);
            continue;
        }
        c->watched = EPOLLIN;
        pthread_mutex_init(&c->lock, NULL);
        c->next = b->conns;
        if (b->conns)
            b->conns->prev = c;
        b->conns = c;
        b->conn_count++;
    }
}

/* Does the input buffer begin with a whole frame (held back by the in-flight limits)? */
static int frame_waiting(const sdfd_binary *b, const connection *c)
{
    sdf_proto_header h;
    return c->in_len >= SDF_PROTO_HEADER_SIZE &&
           !sdf_proto_decode_header(c->in, c->in_len, b->max_payload, &h, NULL) &&
           c->in_len - SDF_PROTO_HEADER_SIZE >= h.length;
}

/* Should the connection be cut off (the limits in the file's comment)? */
static int stalled(const sdfd_binary *b, const connection *c, double now, int out_pending)
{
    double timeout = b->srv->cfg.timeout_seconds;
    if (out_pending && c->out_since > 0 && now - c->out_since > timeout)
        return 1; /* its replies do not move: a client that does not read them */
    if (!c->in_since || frame_waiting(b, c))
        return 0; /* between frames, or a whole frame waits for room: not the client's doing */
    return now - c->last_activity > timeout ||
           now - c->in_since > timeout + (double)c->in_got / MIN_RATE;
}

/* What the other threads share of a connection, read under its lock in one look. */
typedef struct {
    int pending; /* replies queued, not all sent */
    int flying;  /* queries in flight (only grows on this thread) */
    int room;    /* under the in-flight and queued-output limits: frames may go on */
} shared_state;

static shared_state look(connection *c)
{
    pthread_mutex_lock(&c->lock);
    shared_state s = {c->out_head != NULL, c->in_flight,
                      c->in_flight < MAX_IN_FLIGHT && c->out_bytes < MAX_QUEUED_OUT};
    pthread_mutex_unlock(&c->lock);
    return s;
}

/* Does the loop read connection c (and so hand on its frames)? */
static int reading(const sdfd_binary *b, const connection *c, const shared_state *s)
{
    return s->room && !c->closing && !atomic_load(&b->srv->draining);
}

/* Put c on the ready list: the next pass looks at it without waiting for epoll. */
static void make_ready(sdfd_binary *b, connection *c)
{
    if (!c->ready) {
        c->ready = 1;
        c->ready_next = b->ready;
        b->ready = c;
    }
}

/* A TLS handshake's step, when epoll reported `events`: 1 if it has ended (the connection goes
 * on as any other), 0 if it waits on the socket or was closed. */
static int handshake_step(sdfd_binary *b, connection *c, uint32_t events)
{
    if (c->closing || events & (EPOLLERR | EPOLLHUP) || (events && sdfd_bin_handshake(c) < 0)) {
        close_socket(b, c); /* a drain, a peer gone, a failed handshake */
        return 0;
    }
    if (c->handshaken)
        return 1;
    watch(b, c, sdfd_bin_wants_write(c) ? EPOLLOUT : EPOLLIN); /* what GnuTLS waits on */
    return 0;
}

/* Everything there is to do for connection c now: epoll reported `events` (0: it was on one of
 * the loop's lists). Reads one buffer, hands on the frames, sends what is queued, closes it
 * when it is done or broken, and leaves it watched for what it waits on next. */
static void service(sdfd_binary *b, connection *c, uint32_t events)
{
    if (c->dead) { /* closed; it can go once its last job is done */
        reap_later(b, c);
        return;
    }
    if (!c->handshaken && !handshake_step(b, c, events))
        return;
    shared_state s = look(c);
    int readable = (events & (EPOLLIN | EPOLLHUP)) || sdfd_bin_pending(c) > 0 ||
                   (events & EPOLLOUT && sdfd_bin_wants_write(c)); /* a TLS read that waited */
    int fail = (events & EPOLLERR) != 0;
    if (!fail && readable && reading(b, c, &s))
        fail = read_input(b, c) != 0;
    else if (!fail && events & EPOLLHUP)
        fail = 1; /* gone both ways, and not read: nothing can move any more */
    else if (!fail)
        consume_input(b, c); /* frames the limits held back */
    s = look(c);
    if (!fail && s.pending) { /* also a reply queued meanwhile: saves a pass */
        fail = write_output(c) != 0;
        s = look(c);
    }
    if (s.pending && !c->out_since)
        c->out_since = sdfd_now(); /* replies wait from now: stalled() times them */
    int drained = c->closing && !s.pending && !s.flying;
    if (!fail && drained)
        discard_unread(c); /* done: nothing of what is left will be answered */
    if (fail || drained) {
        close_socket(b, c);
        return;
    }
    int reads = reading(b, c, &s);
    uint32_t want = (s.pending ? EPOLLOUT : 0) | (reads ? EPOLLIN : 0);
    if (reads && sdfd_bin_wants_write(c))
        want |= EPOLLOUT; /* a TLS read that stopped on a write (TLS 1.3 key update) */
    watch(b, c, want);
    if (reads && (frame_waiting(b, c) || sdfd_bin_pending(c) > 0))
        make_ready(b, c);
}

/* Once a second: the clocks of every connection (the limits in the file's comment). */
static void sweep(sdfd_binary *b, double now)
{
    double timeout = b->srv->cfg.timeout_seconds;
    for (connection *c = b->conns; c; c = c->next) {
        if (c->dead)
            continue;
        if (!c->handshaken ? now - c->opened > timeout /* a handshake that stopped halfway */
                           : stalled(b, c, now, look(c).pending))
            close_socket(b, c);
    }
}

/* May closed connection c be freed: no job of it left, and on none of the loop's lists? */
static int can_free(sdfd_binary *b, connection *c)
{
    if (!c->dead || c->ready)
        return 0;
    pthread_mutex_lock(&b->notify_lock);
    pthread_mutex_lock(&c->lock);
    int idle = c->in_flight == 0 && !c->notified;
    pthread_mutex_unlock(&c->lock);
    pthread_mutex_unlock(&b->notify_lock);
    return idle;
}

/* Free the connections closed this pass that can go. One that cannot comes back: through the
 * notify list when its last job ends, or through the ready list. */
static void reap(sdfd_binary *b)
{
    for (connection *c = b->reap, *next; c; c = next) {
        next = c->reap_next;
        c->reaping = 0;
        if (!can_free(b, c))
            continue;
        if (c->prev)
            c->prev->next = c->next;
        else
            b->conns = c->next;
        if (c->next)
            c->next->prev = c->prev;
        free_connection(b, c);
    }
    b->reap = NULL;
}

/* The connections whose requests ended on other threads. Each leaves the list (under the lock)
 * before it is looked at, so a request that ends meanwhile puts it back. */
static void serve_notified(sdfd_binary *b)
{
    pthread_mutex_lock(&b->notify_lock);
    connection *list = b->notify;
    b->notify = NULL;
    pthread_mutex_unlock(&b->notify_lock);
    while (list) {
        connection *c = list;
        pthread_mutex_lock(&b->notify_lock);
        list = c->notify_next;
        c->notified = 0;
        pthread_mutex_unlock(&b->notify_lock);
        service(b, c, 0);
    }
}

/* The quiesce, seen on this thread: stop listening and close every connection as soon as it
 * is done (the file's comment). The one walk of every connection a drain makes. */
static void start_drain(sdfd_binary *b)
{
    b->draining = 1;
    epoll_ctl(b->epoll_fd, EPOLL_CTL_DEL, b->listen_fd, NULL);
    close(b->listen_fd);
    b->listen_fd = -1;
    size_t open = b->conn_count;
    for (connection *c = b->conns; c; c = c->next) {
        if (c->dead)
            continue;
        c->closing = 1;
        service(b, c, 0);
    }
    sdfd_log("info", "shutdown",
             "binary: listener closed; %zu of %zu connections closed at once, the rest close "
             "once their replies are out", open - b->conn_count, open);
}

static void *event_loop(void *arg)
{
    sdfd_binary *b = arg;
    struct epoll_event events[MAX_EVENTS];
    b->next_sweep = sdfd_now() + 1;
    while (!atomic_load(&b->stop)) {
        if (atomic_load(&b->quiesced) && !b->draining)
            start_drain(b);
        double wait = b->next_sweep - sdfd_now();
        int timeout = b->ready ? 0 : wait <= 0 ? 0 : wait >= 1 ? 1000 : (int)(wait * 1000) + 1;
        int n = epoll_wait(b->epoll_fd, events, MAX_EVENTS, timeout);
        connection *ready = b->ready; /* last pass's: this pass may start the next one's */
        b->ready = NULL;
        for (int i = 0; i < n; i++) {
            void *who = events[i].data.ptr;
            if (who == &b->wake_fd) {
                uint64_t v;
                ssize_t unused = read(b->wake_fd, &v, sizeof v);
                (void)unused;
            } else if (who == &b->listen_fd) {
                accept_connections(b);
            } else {
                service(b, who, events[i].events);
            }
        }
        serve_notified(b);
        for (connection *c = ready, *next; c; c = next) {
            next = c->ready_next;
            c->ready = 0;
            service(b, c, 0);
        }
        double now = sdfd_now();
        if (now >= b->next_sweep) {
            sweep(b, now);
            b->next_sweep = now + 1;
        }
        reap(b);
    }
    return NULL;
}

int sdfd_binary_start(sdfd_server *srv, sdfd_binary **out)
{
    int port;
    int fd = sdfd_listen(srv->cfg.bin_addr, &port);
    if (fd < 0)
        return -1;
    sdfd_binary *b = calloc(1, sizeof *b);
    if (!b) {
        close(fd);
        return -1;
    }
    b->srv = srv;
    b->listen_fd = fd;
    b->wake_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    b->epoll_fd = epoll_create1(EPOLL_CLOEXEC);
    b->max_payload = (uint32_t)sdfd_max_payload(&srv->cfg);
    pthread_mutex_init(&b->notify_lock, NULL);
    fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK); /* accept4 loops until EAGAIN */
    struct epoll_event wake = {.events = EPOLLIN, .data.ptr = &b->wake_fd};
    struct epoll_event listen = {.events = EPOLLIN, .data.ptr = &b->listen_fd};
    if (b->wake_fd < 0 || b->epoll_fd < 0 ||
        epoll_ctl(b->epoll_fd, EPOLL_CTL_ADD, b->wake_fd, &wake) ||
        epoll_ctl(b->epoll_fd, EPOLL_CTL_ADD, fd, &listen) ||
        pthread_create(&b->thread, NULL, event_loop, b)) {
        close(fd);
        if (b->wake_fd >= 0)
            close(b->wake_fd);
        if (b->epoll_fd >= 0)
            close(b->epoll_fd);
        pthread_mutex_destroy(&b->notify_lock);
        free(b);
        return -1;
    }
    sdfd_log_listening("binary", srv->cfg.bin_addr, port);
    *out = b;
    return 0;
}

/* Shut down the listening socket here, on the caller's thread, so that connects are refused
 * (and the backlog reset) once this returns; the loop closes it and begins the drain. */
void sdfd_binary_quiesce(sdfd_binary *b)
{
    shutdown(b->listen_fd, SHUT_RDWR);
    atomic_store(&b->quiesced, 1);
    sdfd_bin_wake(b);
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
    sdfd_bin_wake(b);
    pthread_join(b->thread, NULL);
    for (connection *c = b->conns, *next; c; c = next) {
        next = c->next;
        flush_connection(b, c);
        sdfd_bin_end_tls(b, c); /* its close_notify goes out before the socket closes */
        if (c->fd >= 0)
            close(c->fd);
        free_connection(b, c);
    }
    if (b->listen_fd >= 0)
        close(b->listen_fd);
    close(b->wake_fd);
    close(b->epoll_fd);
    pthread_mutex_destroy(&b->notify_lock);
    free(b);
}
