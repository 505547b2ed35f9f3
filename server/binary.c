/* binary.c - the binary protocol listener: one thread polls the listening socket and every
 * connection (non-blocking) and splits the byte stream into frames, which
 * sdfd_bin_handle_frame (binrequests.c) answers or hands on; replies finished on other
 * threads are appended to the connection's output queue (binconn.c), and the poll loop is
 * woken through an eventfd. Replies therefore leave in completion order, matched by request id.
 *
 * Limits: a frame's length is checked against max_payload before the input buffer grows;
 * at most 64 queries per connection are in flight and at most 64 MiB of replies wait unsent,
 * beyond which the connection is not read (TCP backpressure on a client that does not
 * read); a connection is closed when its replies have not moved for the timeout (a client
 * that does not read), when it is idle mid-frame for the timeout, and when a frame (the
 * first one from the connection's start, the next ones from their first byte) takes longer
 * than the timeout plus a second per MIN_RATE bytes (a client that trickles bytes, or
 * connects and never sends); idle between frames it stays open. A framing error gets one
 * ERROR frame and the connection closes after it is sent; a frame with no room under
 * --max-buffered-bytes gets an ERROR and is read and dropped, and the connection goes on.
 * A connection that goes away with queries in flight is freed when the last of them
 * completes.
 *
 * With --bin-tls every connection is a GnuTLS session on the same non-blocking socket
 * (binconn.c's I/O): the handshake is taken a step at a time as poll says the socket is
 * ready for what GnuTLS waits on, and a connection whose handshake has not ended --timeout
 * after it was accepted is closed, so a client that stops halfway holds a slot no longer
 * than an idle one. Records GnuTLS has decrypted but not yet handed over do not show in
 * poll: such a connection is read without waiting. The limits above apply unchanged to
 * the decrypted bytes. */
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

#include "binconn.h"
#include "binrequests.h"
#include "errors.h"
#include "log.h"
#include "net.h"
#include "proto.h"

#define MAX_IN_FLIGHT 64
#define INPUT_BASE (64 * 1024) /* a connection's input buffer between big frames */
#define MAX_QUEUED_OUT (64u << 20) /* unsent reply bytes before we stop reading */
#define MIN_RATE (64.0 * 1024) /* bytes a second a frame must arrive at, after the timeout */

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
    sdfd_route route;
    const char *what;
    sdfd_bin_frame_kind(h.type, &route, &what);
    sdfd_bin_account(b, route, what, sdfd_http_status(SDFD_EBUSY), 0, sdfd_now(), frame, 0);
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

static void close_socket(sdfd_binary *b, connection *c)
{
    sdfd_bin_end_tls(b, c);
    if (c->fd >= 0) {
        close(c->fd);
        c->fd = -1;
        b->conn_count--;
    }
    b->dead_count += !c->dead;
    c->dead = 1;
    free(c->in); /* nothing reads it any more; its room goes back to the budget */
    c->in = NULL;
    sdfd_buffer_release(b->srv, c->in_cap);
    c->in_cap = c->in_len = 0;
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
        if (!c->handshaken && sdfd_tls_session_begin(b->srv->tls, fd, &c->tls, &c->cert)) {
            close(fd);
            free(c);
            continue;
        }
        pthread_mutex_init(&c->lock, NULL);
        c->next = b->conns;
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
            b->dead_count--;
            free_connection(b, c);
        } else {
            link = &c->next;
        }
    }
}

/* What the poll loop waits on for connection c. */
static short connection_events(connection *c)
{
    if (!c->handshaken) /* the handshake: what GnuTLS waits on */
        return sdfd_bin_wants_write(c) ? POLLOUT : POLLIN;
    pthread_mutex_lock(&c->lock);
    int room = c->in_flight < MAX_IN_FLIGHT && c->out_bytes < MAX_QUEUED_OUT;
    short events = (c->out_head ? POLLOUT : 0) | (!c->closing && room ? POLLIN : 0);
    if (c->out_head && !c->out_since)
        c->out_since = sdfd_now(); /* replies wait from now: stalled() times them */
    pthread_mutex_unlock(&c->lock);
    /* A TLS read that stopped on a write (TLS 1.3 can answer a key update) needs POLLOUT. */
    if (events & POLLIN && sdfd_bin_wants_write(c))
        events |= POLLOUT;
    return events;
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
        int buffered = 0; /* a connection has TLS records decrypted and unread */
        fds[n++] = (struct pollfd){b->wake_fd, POLLIN, 0};
        fds[n++] = (struct pollfd){atomic_load(&b->quiesced) ? -1 : b->listen_fd, POLLIN, 0};
        for (connection *c = b->conns; c; c = c->next) {
            if (c->dead)
                continue;
            owners[n] = c;
            fds[n++] = (struct pollfd){c->fd, connection_events(c), 0};
            buffered |= (fds[n - 1].events & POLLIN) && sdfd_bin_pending(c) > 0;
        }
        poll(fds, n, buffered ? 0 : 1000);
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
            if (!c->handshaken) {
                if (re && (re & (POLLERR | POLLNVAL) || sdfd_bin_handshake(c) < 0))
                    close_socket(b, c);
                else if (now - c->opened > timeout)
                    close_socket(b, c); /* a handshake that stopped halfway */
                continue;
            }
            if ((fds[i].events & POLLIN) && sdfd_bin_pending(c) > 0)
                re |= POLLIN;
            if (sdfd_bin_wants_write(c) && (re & POLLOUT))
                re |= POLLIN; /* a TLS read that waited on a write */
            int fail = (re & (POLLERR | POLLNVAL)) != 0;
            if (!fail && (re & (POLLIN | POLLHUP)) && !c->closing)
                fail = read_input(b, c) != 0;
            else if (!fail && !c->closing)
                consume_input(b, c); /* frames held back by the in-flight limit */
            /* One look under the lock for an idle connection: this runs for every one. */
            pthread_mutex_lock(&c->lock);
            int pending = c->out_head != NULL, flying = c->in_flight;
            pthread_mutex_unlock(&c->lock);
            if (!fail && pending) { /* also a reply queued since the poll began: saves a pass */
                fail = write_output(c) != 0;
                pthread_mutex_lock(&c->lock);
                pending = c->out_head != NULL;
                pthread_mutex_unlock(&c->lock);
            }
            int drained = !pending && flying == 0; /* in_flight only grows on this thread */
            if (fail || stalled(b, c, now, pending) || (c->closing && drained))
                close_socket(b, c);
        }
        if (b->dead_count) /* a walk of every connection: only when one can go */
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
    close(b->listen_fd);
    close(b->wake_fd);
    free(b);
}

