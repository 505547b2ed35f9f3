/* binconn.c - what the binary front end's connections share across threads (binconn.h):
 * queueing a reply frame, from any thread; counting and logging a request; and a request's
 * end, which hands the connection to the event loop and wakes it. And their byte I/O on the
 * loop's thread: plain
 * recv/send, or GnuTLS records (--bin-tls) on the same non-blocking socket, so the loop
 * treats both alike. */
#include "transport/binconn.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "core/errors.h"
#include "core/log.h"
#include "core/utf8.h"
#include "ops/admission.h"

void sdfd_bin_wake(sdfd_binary *b)
{
    uint64_t one = 1;
    ssize_t unused = write(b->wake_fd, &one, sizeof one);
    (void)unused;
}

void sdfd_bin_enqueue(connection *c, char *data, size_t len)
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

void sdfd_bin_send_error(connection *c, uint32_t id, int err, const char *message)
{
    char *frame = malloc(512), text[400];
    if (!frame)
        return;
    sdfd_utf8_clean(text, sizeof text, message); /* it may quote the client's bytes */
    size_t n = sdf_proto_encode_error(frame, 512, id, (uint16_t)sdfd_http_status(err),
                                      sdfd_errname(err), text);
    sdfd_bin_enqueue(c, frame, n);
}

void sdfd_bin_account(sdfd_binary *b, const sdfd_op *op, const char *what, int status,
                      size_t points, double start, size_t bytes_in, size_t bytes_out)
{
    sdfd_account(b->srv, &(sdfd_answered){.op = op, .binary = 1, .what = what, .status = status,
                                          .points = points, .start = start,
                                          .bytes_in = bytes_in, .bytes_out = bytes_out});
}

/* The count goes down and c goes on the list under one hold of notify_lock: the loop frees a
 * closed connection only with nothing in flight and off the list (binary.c's can_free), so it
 * cannot free c between the two. Only the push onto an empty list wakes the loop: a list with
 * entries has a wake on its way, sent by the thread that pushed the first one. */
void sdfd_bin_request_finished(sdfd_binary *b, connection *c)
{
    pthread_mutex_lock(&b->notify_lock);
    pthread_mutex_lock(&c->lock);
    c->in_flight--;
    pthread_mutex_unlock(&c->lock);
    int first = !b->notify;
    if (!c->notified) {
        c->notified = 1;
        c->notify_next = b->notify;
        b->notify = c;
    }
    pthread_mutex_unlock(&b->notify_lock);
    if (first)
        sdfd_bin_wake(b);
    atomic_fetch_sub(&b->srv->in_flight, 1); /* last: shutdown frees b once it reaches 0 */
}

void sdfd_bin_frame_kind(uint8_t type, const sdfd_op **op, const char **what)
{
    *op = sdfd_op_of_frame(type);
    *what = sdfd_op_frame_name(type);
}

/* GnuTLS's result as recv/send's: a would-block is EAGAIN; the peer's close_notify, or a
 * stream that simply ends, is the end of the stream; anything else fails the connection. */
static ssize_t tls_result(ssize_t rc)
{
    if (rc >= 0)
        return rc;
    if (rc == GNUTLS_E_AGAIN || rc == GNUTLS_E_INTERRUPTED) {
        errno = EAGAIN;
        return -1;
    }
    if (rc == GNUTLS_E_PREMATURE_TERMINATION)
        return 0;
    errno = EPROTO;
    return -1;
}

ssize_t sdfd_bin_recv(connection *c, void *buf, size_t n)
{
    if (!c->tls)
        return recv(c->fd, buf, n, 0);
    ssize_t rc = gnutls_record_recv(c->tls, buf, n);
    c->read_wants_write = rc == GNUTLS_E_AGAIN && gnutls_record_get_direction(c->tls) == 1;
    return tls_result(rc);
}

ssize_t sdfd_bin_send(connection *c, const void *buf, size_t n)
{
    if (!c->tls)
        return send(c->fd, buf, n, MSG_NOSIGNAL);
    return tls_result(gnutls_record_send(c->tls, buf, n));
}

int sdfd_bin_handshake(connection *c)
{
    int rc = gnutls_handshake(c->tls);
    if (rc == GNUTLS_E_SUCCESS) {
        c->handshaken = 1;
        return 1;
    }
    if (!gnutls_error_is_fatal(rc))
        return 0; /* EAGAIN, or a warning alert: go on when the socket is ready */
    sdfd_log("warn", "tls_handshake", "binary connection: %s", gnutls_strerror(rc));
    return -1;
}

int sdfd_bin_wants_write(const connection *c)
{
    if (!c->tls)
        return 0;
    return c->handshaken ? c->read_wants_write : gnutls_record_get_direction(c->tls) == 1;
}

size_t sdfd_bin_pending(const connection *c)
{
    return c->tls && c->handshaken ? gnutls_record_check_pending(c->tls) : 0;
}

void sdfd_bin_end_tls(sdfd_binary *b, connection *c)
{
    if (!c->tls)
        return;
    if (c->handshaken && c->fd >= 0)
        gnutls_bye(c->tls, GNUTLS_SHUT_WR); /* non-blocking: one try; the close follows */
    sdfd_tls_session_end(b->srv->tls, c->tls, c->cert);
    c->tls = NULL;
    c->cert = NULL;
}
