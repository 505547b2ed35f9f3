/* binconn.h - the binary front end's connections, their reply queues and their byte I/O,
 * plain or TLS (binconn.c), used by
 * binary.c, which owns the sockets (it watches them with epoll, splits their bytes into frames
 * and hands each frame to binrequests.c), and by binrequests.c, which answers a frame or starts
 * the work that will. Replies go out through a connection's queue (sdfd_bin_enqueue), from any
 * thread, and the request's end (sdfd_bin_request_finished) puts the connection on the list
 * the loop looks at next. Private to those three files. */
#ifndef SDFD_BINCONN_H
#define SDFD_BINCONN_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/socket.h>
#include <sys/types.h>

#include <gnutls/gnutls.h>

#include "ops/optable.h"
#include "proto.h"
#include "state/server.h"
#include "transport/tls.h"

/* As binary.h declares it (C11 allows the repeat): this header does not include binary.h,
 * whose module includes this one. */
typedef struct sdfd_binary sdfd_binary;

typedef struct out_frame {
    struct out_frame *next;
    char *data;   /* frame bytes (malloc'd) */
    size_t len, sent;
} out_frame;

typedef struct connection connection;

struct connection {
    int fd;
    gnutls_session_t tls;       /* --bin-tls: the session over fd, else NULL */
    sdfd_tls_cert *cert;        /* ... and the certificate it holds (tls.h) */
    int handshaken;             /* TLS: the handshake is done; plain: always 1 */
    double opened;              /* accepted at: the handshake must end within --timeout */
    int read_wants_write;       /* TLS: the last read stopped on a write, not a read */
    struct sockaddr_storage peer; /* for the per-address connection limit */
    unsigned char *in;
    size_t in_len, in_cap;
    size_t skip;                /* bytes of a refused frame still to read and drop */
    double last_activity;
    double in_since;            /* when the frame being read began (0: between frames) */
    size_t in_got;              /* bytes read since in_since */
    double out_since;           /* when the queued output last moved (0: none queued) */
    int closing;                /* send what is queued, then close */
    int dead;                   /* socket closed; waiting for in-flight jobs */
    pthread_mutex_t lock;       /* out queue and in_flight: shared with the dispatcher */
    out_frame *out_head, *out_tail;
    size_t out_bytes;           /* queued, not yet sent */
    int in_flight;
    int authenticated;          /* sent AUTH with the --token */
    uint32_t watched;           /* the epoll events registered for fd */
    connection *prev, *next;    /* every connection not yet freed (sdfd_binary.conns) */
    /* The loop's lists (binary.c): each flag says the connection is on that list. */
    connection *ready_next;     /* to look at on the next pass without waiting */
    connection *reap_next;      /* closed this pass: free it at the pass's end if it can go */
    int ready, reaping;
    connection *notify_next;    /* a request ended on another thread (under notify_lock) */
    int notified;
};

struct sdfd_binary {
    sdfd_server *srv;
    int listen_fd, wake_fd, epoll_fd;
    pthread_t thread;
    atomic_int stop, quiesced;
    connection *conns;
    size_t conn_count;          /* sockets open */
    connection *ready, *reap;   /* the loop's own lists */
    pthread_mutex_t notify_lock; /* notify, and each connection's notified and notify_next */
    connection *notify;         /* connections whose requests ended on other threads */
    double next_sweep;          /* when the loop next checks every connection's clocks */
    int draining;               /* the loop has seen the quiesce: it closes its connections */
    uint32_t max_payload;
};

/* Wake the event loop (a reply was queued from another thread). */
void sdfd_bin_wake(sdfd_binary *b);
/* Queue a frame; takes ownership of data. Any thread. */
void sdfd_bin_enqueue(connection *c, char *data, size_t len);
/* Queue an ERROR frame answering request `id`. */
void sdfd_bin_send_error(connection *c, uint32_t id, int err, const char *message);
/* One request: metrics and a log line, as the HTTP side does. */
void sdfd_bin_account(sdfd_binary *b, const sdfd_op *op, const char *what, int status,
                      size_t points, double start, size_t bytes_in, size_t bytes_out);
/* A request of connection c has been answered (or refused after it was counted): c goes on
 * the list the loop looks at next (its reply is sent, the frames held back for the in-flight
 * limit go on), and the loop is woken. */
void sdfd_bin_request_finished(sdfd_binary *b, connection *c);

/* A connection's bytes, through TLS or not. Like recv and send: the count, 0 at the end of
 * the stream (recv), or -1 with errno (EAGAIN: nothing can move now; wait for
 * sdfd_bin_wants_write ? EPOLLOUT : EPOLLIN). A send that was refused for EAGAIN must be
 * repeated with the same bytes (GnuTLS holds the record it had begun). */
ssize_t sdfd_bin_recv(connection *c, void *buf, size_t n);
ssize_t sdfd_bin_send(connection *c, const void *buf, size_t n);
/* Take the TLS handshake as far as the socket allows: 1 done, 0 not yet, -1 failed (the
 * connection is to be closed; logged). */
int sdfd_bin_handshake(connection *c);
/* Is the handshake, or the last read, waiting to write (TLS can need either way)? */
int sdfd_bin_wants_write(const connection *c);
/* Bytes TLS has decrypted and not yet handed over: readable without the socket being so. */
size_t sdfd_bin_pending(const connection *c);
/* Shut down and free the TLS session (if any); the socket stays open. */
void sdfd_bin_end_tls(sdfd_binary *b, connection *c);

/* A frame type's operation (NULL: none) and name, as its requests are counted and logged. */
void sdfd_bin_frame_kind(uint8_t type, const sdfd_op **op, const char **what);

#endif
