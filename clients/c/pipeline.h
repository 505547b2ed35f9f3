/* pipeline.h - libsdfclient's machinery under the public calls (internal): the handle, its
 * table of requests in flight (indexed by request id minus the oldest id, as ids are handed
 * out in order), the reader of reply frames, sending, and replacing a lost connection
 * (sdfclient.h, "Re-sending"). sdfclient.c builds the requests and hands their replies back
 * through these; nothing here is exported from the shared library. */
#ifndef SDFC_PIPELINE_H
#define SDFC_PIPELINE_H

#include <stddef.h>
#include <stdint.h>
#include <sys/uio.h>

#include "proto.h"
#include "sdfclient.h"
#include "transport.h"

enum { SDFC__FREE = 0, SDFC__IN_FLIGHT, SDFC__DONE };

typedef struct sdfc__pending {
    int state;
    int status;              /* once DONE: 0 or SDFC_ESERVER */
    uint8_t reply_type;      /* the frame type that answers it */
    int resent;              /* sent again on a new connection already */
    int unavailable;         /* refused 503 EUNAVAILABLE: to go again on the next connection */
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
} sdfc__pending;

/* Where the reader stands in the current frame. */
typedef struct sdfc__reader {
    unsigned char hdr[24];   /* header, then a RESULT's prefix */
    size_t got;              /* bytes of the current frame read so far */
    int routed;              /* the header is in and decoded */
    sdf_proto_header h;      /* h.request_id: the request it answers (0: the connection);
                                looked up anew each time, as sending may move the table */
    unsigned char *buf;      /* non-RESULT payload */
} sdfc__reader;

struct sdfc_client {
    sdfc__conn conn;
    unsigned generation;     /* connections opened so far */
    int broken;              /* sticky error code, 0 while usable */
    int reply_timeout_ms;
    int connect_timeout_ms;
    char *host;              /* where to connect again, and how */
    int port;
    sdfc__tls *tls;
    int resend;
    int reconnecting;        /* in reconnect(): a lost connection breaks the handle */
    int opening;             /* in sdfc__open(): a lost connection is its to try again */
    size_t unavailable;      /* requests in flight refused as unavailable */
    char *token;             /* the last token the server took; NULL: none */
    size_t token_len;
    sdfc_stats stats;
    uint32_t max_points;     /* from HELLO; 0 = unknown */
    uint32_t max_payload;
    uint32_t next_id;
    sdfc__pending *pend;     /* pend[head .. head + n) are ids base_id .. */
    size_t head, n, cap;
    uint32_t base_id;
    size_t in_flight;
    uint64_t done_seq;
    sdfc__reader rx;
    sdfc_server_err err;
};

/* The handle's sticky error: the first code given; returns the one kept. */
SDFC__HIDDEN int sdfc__set_broken(sdfc_client *c, int code);

/* The entry of a request in flight (not yet claimed), or NULL. The table may move whenever
 * a frame is read or a request added: look an entry up again after either. */
SDFC__HIDDEN sdfc__pending *sdfc__lookup(sdfc_client *c, uint32_t id);
/* A new entry for the next id, in flight; NULL when out of memory or ids. */
SDFC__HIDDEN sdfc__pending *sdfc__add_entry(sdfc_client *c, uint32_t *id);
/* Hand a finished entry back: its status, its error (if any) made the handle's. */
SDFC__HIDDEN int sdfc__claim(sdfc_client *c, sdfc__pending *p);
/* Forget an entry whose request could not be sent. */
SDFC__HIDDEN void sdfc__drop(sdfc_client *c, sdfc__pending *p);
/* Free what an entry owns and zero it. */
SDFC__HIDDEN void sdfc__free_entry(sdfc__pending *p);

/* Keep what re-sending `p` needs: a copy of `frame` (header and prefix), `points` by
 * reference. 0 or SDFC_ENOMEM. */
SDFC__HIDDEN int sdfc__keep_frame(sdfc__pending *p, const void *frame, size_t len,
                                  const void *points, size_t points_len);
/* Send the iovecs in full, reading replies while the socket is full; 0 or the handle's
 * error. The request they hold must already be in the table. */
SDFC__HIDDEN int sdfc__tx(sdfc_client *c, struct iovec *iov, int iovcnt);
/* Block until at least one more reply frame completes, or the reply timeout passes. */
SDFC__HIDDEN int sdfc__rx_one(sdfc_client *c);

/* Send a frame with no points that the server answers with `reply` and wait for it. On 0
 * *out is the DONE entry with its payload, for the caller to read and claim; otherwise the
 * entry is gone (SDFC_ESERVER: the refusal is the handle's error). */
SDFC__HIDDEN int sdfc__call(sdfc_client *c, uint8_t type, const void *payload, size_t len,
                            uint8_t reply, sdfc__pending **out);
/* A HELLO_OK entry into *out and the handle's limits; claims p. */
SDFC__HIDDEN int sdfc__decode_hello(sdfc_client *c, sdfc__pending *p, sdfc_hello_info *out);

/* A handshake lost with its connection is tried this many times in all (with `resend`). */
#define SDFC__CONNECT_ATTEMPTS 3

/* Open a new connection in place of the current one (closed first) and send AUTH with the
 * kept token (if any) and, with `hello`, HELLO, waiting for their replies. With `resend`, a
 * connection closed or reset before they are answered (a balancer may hand it to a replica
 * that is going away) is opened again, SDFC__CONNECT_ATTEMPTS times in all, 50 and 100 ms
 * apart. 0, sdfc__conn_open's code, SDFC_ESERVER for a refused AUTH, or the handshake's. */
SDFC__HIDDEN int sdfc__open(sdfc_client *c, int hello);

/* At most cap - 1 bytes of s, NUL-terminated, into dst. */
SDFC__HIDDEN void sdfc__copy_str(char *dst, size_t cap, const char *s, size_t len);

#endif
