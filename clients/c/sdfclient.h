/* sdfclient.h - libsdfclient, a C client of sdfd's binary protocol (proto/PROTOCOL.md).
 *
 * One sdfc_client is one TCP connection to sdfd's --bin address, plain or, for a server
 * started with --bin-tls, inside TLS 1.2+ (GnuTLS) with the server's certificate verified.
 * It sends HELLO, AUTH, LIST_MESHES, and pipelined QUERY and VOLUME_QUERY requests: send many
 * (each with its own caller-owned result buffer), then receive them by request id in any
 * order. With sdfc_options.resend, requests a connection took with it when it closed, and
 * queries a server going away refused, are sent again, once, on a new one ("Re-sending"
 * below). Linking it pulls in only the protocol
 * codec and GnuTLS, never libsdf or Embree.
 *
 * Conventions:
 *  - Every function that can fail returns int: 0 (SDFC_OK) or a negative SDFC_E* code;
 *    sdfc_strerror() names it. Codes that mean what an SDF_E* code of libsdf's sdf.h means
 *    have its value (SDFC_EINVAL == SDF_EINVAL ...), so one switch serves both; the codes
 *    libsdf has no word for (cannot connect, timed out, closed, the server refused) lie
 *    below -100. This header does not include sdf.h, so that it installs on its own.
 *  - SDFC_ESERVER: the server answered with an ERROR frame; sdfc_server_error() holds its
 *    HTTP status, code name ("ENOTFOUND", ...) and message. The connection stays usable.
 *  - Any other error on a connected handle (I/O, timeout, closed, a malformed reply) leaves
 *    the byte stream in an unknown state: the handle then fails every call with that same
 *    code; sdfc_close() it and connect again. SDFC_EINVAL (a bad argument, refused before
 *    anything is sent) is the exception and leaves the handle as it was. A connection that
 *    closes under a handle with `resend` set is first replaced, as "Re-sending" says.
 *  - Thread-safety: a handle is used by one thread at a time; distinct handles are
 *    independent (the library has no global state).
 *  - Points are float32 x, y, z triples in host order; results are 32-bit words in the
 *    layout of PROTOCOL.md's RESULT (floats; closest's fifth word a uint32 triangle id).
 *    The library requires a little-endian host, as the protocol's byte order is.
 *  - Prefix: sdfc_ (client), so that it never collides with libsdf's sdf_ in one program.
 */
#ifndef SDFCLIENT_H
#define SDFCLIENT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SDFC_VERSION_MAJOR 0
#define SDFC_VERSION_MINOR 2

enum {
    SDFC_OK = 0,
    SDFC_EINVAL = -1,        /* a bad argument (NULL, empty or long name, unknown mode) */
    SDFC_ENOMEM = -2,        /* out of memory */
    SDFC_EIO = -3,           /* a socket call failed (errno has the reason) */
    SDFC_ELIMIT = -7,        /* a result buffer too small, more points than the server's
                                max_points, a reply larger than this library accepts */
    SDFC_EPROTO = -13,       /* a reply that does not follow PROTOCOL.md */
    SDFC_ESERVER = -101,     /* the server refused the request: see sdfc_server_error() */
    SDFC_ECONNECT = -102,    /* cannot resolve the host or connect to it */
    SDFC_ETIMEDOUT = -103,   /* no reply within the reply timeout (or no connection within
                                the connect timeout) */
    SDFC_ECLOSED = -104,     /* the server closed the connection (after a connection-level
                                ERROR, its request id 0, sdfc_server_error() holds it) */
    SDFC_ENOREQUEST = -105,  /* sdfc_wait() for an id that is not in flight on this handle */
    SDFC_ETLS = -106,        /* the TLS handshake failed (e.g. the port is not --bin-tls), or
                                a TLS record did not decrypt */
    SDFC_ECERT = -107,       /* the server's certificate did not verify: not signed by a CA
                                of ca_file (or the system's), expired, or not for this host */
};

/* A static, human-readable message for an SDFC_E* code. */
const char *sdfc_strerror(int err);

typedef struct sdfc_client sdfc_client;

typedef struct sdfc_options {
    int connect_timeout_ms; /* 0 = 10000; < 0 = wait as long as the system does */
    int reply_timeout_ms;   /* the longest any call waits for the next reply frame to arrive
                               in full (or for the socket to take more of a request);
                               0 = 120000; < 0 = forever */
    const char *token;      /* non-NULL: send AUTH with it right after connecting */
    int tls;                /* non-zero: a server started with --bin-tls. The frames travel
                               inside TLS 1.2 or 1.3; the handshake (within the connect
                               timeout) verifies the server's certificate against ca_file
                               and that it names `host` (a DNS name, or an IP address
                               against the certificate's IP addresses) */
    const char *ca_file;    /* with tls: a PEM file of the CA certificates to trust; NULL:
                               the system's. Without tls it must be NULL */
    int resend;             /* non-zero: re-send requests a closed connection took with it
                               ("Re-sending" below); `points` arrays must then stay valid
                               until their request is waited for */
} sdfc_options;

/* Connect to HOST:PORT (a name or numeric address; IPv4 or IPv6). `opts` may be NULL
 * (defaults). On success *out is a new handle (free it with sdfc_close); on failure *out is
 * NULL and the code is SDFC_ECONNECT, SDFC_ETIMEDOUT, SDFC_ENOMEM, with tls SDFC_ETLS or
 * SDFC_ECERT, SDFC_EINVAL for a ca_file that does not load or holds no PEM certificate (or
 * is given without tls), or the AUTH's error (SDFC_ESERVER with EUNAUTHORIZED for a wrong
 * token: its message is lost with the handle, so sdfc_connect prints nothing and callers
 * that need it call sdfc_auth themselves).
 *
 * Re-sending (opts->resend): sdfd's replicas behind a load balancer come and go, and a
 * connection to one that died closes or is reset with requests still unanswered. When that
 * happens inside any call on the handle (the server closed it, without a connection-level
 * ERROR, or a send or receive failed with EPIPE or ECONNRESET), and every request in
 * flight is one that may go again, the handle opens a new connection to the same host and
 * port (and TLS settings), sends AUTH again with the last token that succeeded (from
 * opts->token or sdfc_auth) and HELLO (its limits replace the old ones), then sends every
 * unanswered request again with its id, from its own points array, and the call goes on.
 * Replies that had arrived are kept. The requests that may go again are the read-only
 * ones: QUERY (sdfc_send_query, sdfc_query), VOLUME_QUERY, HELLO and LIST_MESHES; an AUTH
 * in flight is not, so a connection lost during sdfc_auth is its error. Each request is
 * sent again at most once: a connection that closes while any request it carries was
 * already re-sent, a new connection that fails, or a failure while replacing one, is the
 * error of the call that met it (SDFC_ECLOSED, or the reconnection's SDFC_ECONNECT,
 * SDFC_ETIMEDOUT ...; a refused AUTH is SDFC_ECLOSED with sdfc_server_error() set) and the
 * handle is unusable as for any such error. Timeouts and malformed replies are never
 * re-sent.
 * A query (QUERY or VOLUME_QUERY) that the server refuses with 503 EUNAVAILABLE (a draining
 * replica, or one still loading) is not its caller's error either, the first time: it stays
 * in flight while the replies to the others in flight on that connection arrive, and once
 * only such refused queries are left, the handle replaces the connection as above and
 * sends them again there (a new request sent meanwhile goes on the old connection, and is
 * refused and sent again in turn). Refused a second time, it is SDFC_ESERVER as any
 * refusal, and the handle stays usable.
 * A new connection (sdfc_connect's own, with opts->token, or a replacement) that is closed
 * or reset before its AUTH and HELLO are answered, or during its TLS handshake, as a
 * balancer does when it hands it to a replica that is going away, is opened again, three
 * times in all, 50 and 100 ms apart; the last attempt's failure is the call's.
 * sdfc_get_stats() counts connections and re-sent requests. */
int sdfc_connect(const char *host, int port, const sdfc_options *opts, sdfc_client **out);

/* A handle's counters. */
typedef struct sdfc_stats {
    uint64_t connects;  /* connections opened (TCP, and with TLS its handshake done), the
                           first and every replacement (or attempt at one) alike */
    uint64_t resent;    /* requests sent again on a new connection */
} sdfc_stats;
int sdfc_get_stats(const sdfc_client *c, sdfc_stats *out);

/* Close the connection and free the handle (NULL is allowed). Requests still in flight are
 * abandoned; their result buffers are not written after this returns. */
void sdfc_close(sdfc_client *c);

/* The last ERROR frame this handle received for a call that returned SDFC_ESERVER (or for
 * the connection, before SDFC_ECLOSED). Strings are NUL-terminated, cut to fit. Valid until
 * the next call on the handle; zeroed when there was none. */
typedef struct sdfc_server_err {
    int status;        /* the HTTP status the same error gets over HTTP: 401, 404, 422 ... */
    char code[32];     /* "EUNAUTHORIZED", "ENOTFOUND", "ENONFINITE" ... */
    char message[512];
} sdfc_server_err;
const sdfc_server_err *sdfc_server_error(const sdfc_client *c);

/* HELLO: the server's limits. Also remembered by the handle, which then refuses (with
 * SDFC_ELIMIT, sending nothing) a query of more than max_points points. */
typedef struct sdfc_hello_info {
    int version;             /* protocol version, 1 */
    uint32_t max_payload;    /* the largest request payload the server takes, in bytes */
    uint32_t max_points;     /* the most points one QUERY may hold */
    char server[128];        /* the server's version string, NUL-terminated */
} sdfc_hello_info;
int sdfc_hello(sdfc_client *c, sdfc_hello_info *out);

/* AUTH with `token` (len bytes). A wrong token: SDFC_ESERVER (EUNAUTHORIZED), and the
 * server closes the connection, so the handle is unusable after it. A token the server
 * took is kept for the connections that replace this one (opts->resend). */
int sdfc_auth(sdfc_client *c, const char *token, size_t len);

/* LIST_MESHES: writes min(cap, count) entries to `out` (cap may be 0 and out NULL to ask
 * only how many) and the server's count to *count. */
typedef struct sdfc_mesh {
    char name[256];     /* NUL-terminated (names are at most 255 bytes) */
    uint64_t triangles;
    int closed;         /* 1 if every edge has exactly two triangles */
    int auto_sign;      /* the sign code `auto` resolves to (sdfc_sign) */
} sdfc_mesh;
int sdfc_list_meshes(sdfc_client *c, sdfc_mesh *out, size_t cap, size_t *count);

/* Query modes and sign methods; the values are the wire codes. */
typedef enum sdfc_mode {
    SDFC_SIGNED = 0,            /* 1 word per point: distance, negative inside */
    SDFC_DISTANCE = 1,          /* 1: unsigned distance */
    SDFC_GRADIENT = 2,          /* 4: distance, gradient x y z */
    SDFC_CLOSEST = 3,           /* 5: distance, closest x y z, triangle id (uint32) */
    SDFC_FILTERED = 4,          /* 1: the filtered field g (docs/filtered.md) */
    SDFC_FILTERED_GRADIENT = 5, /* 4: g, its gradient x y z */
} sdfc_mode;

typedef enum sdfc_sign {
    SDFC_SIGN_AUTO = 0,
    SDFC_SIGN_PSEUDONORMAL = 1,
    SDFC_SIGN_WINDING = 2,
    SDFC_SIGN_RAYCAST = 3,
    SDFC_SIGN_NONE = 4,
} sdfc_sign;

/* "signed", "distance", "gradient", "closest", "filtered", "filtered-gradient" and
 * "auto", "pseudonormal", "winding", "raycast", "none": 0 or SDFC_EINVAL. */
int sdfc_mode_from_name(const char *name, sdfc_mode *out);
int sdfc_sign_from_name(const char *name, sdfc_sign *out);
/* 32-bit words per point of a mode's result (1, 1, 4, 5, 1, 4); 0 for an unknown mode. */
unsigned sdfc_words(sdfc_mode mode);
/* Bytes of result buffer a query of `count` points in `mode` needs: 4 * words * count. */
size_t sdfc_result_size(sdfc_mode mode, uint32_t count);

/* The filtered modes' parameters (PROTOCOL.md's FILTER block; docs/filtered.md says what
 * each means). A zeroed struct, or a NULL pointer, means the server's defaults. */
enum { SDFC_FILTER_GRID = 1, SDFC_FILTER_UNSIGNED = 2, SDFC_FILTER_WIDE_BUMP = 4,
       SDFC_FILTER_SAMPLE_GRADIENT = 8 };
enum { SDFC_SMOOTH_NONE = 0, SDFC_SMOOTH_SPHERE = 1, SDFC_SMOOTH_BOX = 2, SDFC_SMOOTH_MESH = 3 };
typedef struct sdfc_filter {
    int kernel;            /* 0 Gaussian, 1 bump */
    unsigned flags;        /* SDFC_FILTER_* bits */
    uint32_t samples;      /* n; 0 = 64 */
    uint32_t min_samples;  /* adaptive N_min; 0 = off */
    double cap, a, b;      /* f_c, Gaussian a, bump width b; 0 = defaults */
    double medial;         /* adaptive medial threshold; 0 = default */
    uint64_t seed;
    int smooth;            /* SDFC_SMOOTH_*: where to filter (NONE: everywhere) */
    double shape[6];       /* SPHERE: centre x y z, radius; BOX: x0 y0 z0 x1 y1 z1 */
    const char *smooth_mesh; /* SMOOTH_MESH: the loaded mesh's name (1..255 bytes) */
    double depth, scale;   /* s_d, s_r; 0 = defaults */
} sdfc_filter;

/* Send a QUERY of `count` points (3 * count floats at `points`) on mesh `mesh` (1..255
 * bytes, NUL-terminated) and return at once with its id in *request_id. `filter` is read
 * only for the filtered modes (NULL: defaults). The reply is written to `result`, which must
 * hold sdfc_result_size(mode, count) bytes (`result_size` says how many it has: fewer is
 * SDFC_ELIMIT, nothing sent) and must stay valid, untouched by the caller, until
 * sdfc_wait() returns this id or the handle is closed. `points` is read only during the
 * call, unless the handle re-sends (opts->resend): then it is read again if the request is
 * re-sent, so it too must stay valid and unchanged until the id is waited for. While the
 * socket is full, the call reads replies that have arrived (into their own buffers), so
 * any number of requests may be sent before waiting. */
int sdfc_send_query(sdfc_client *c, const char *mesh, sdfc_mode mode, sdfc_sign sign,
                    const sdfc_filter *filter, const float *points, uint32_t count,
                    void *result, size_t result_size, uint32_t *request_id);

/* A volume query's reconstruction between the nodes (docs/volumes.md, "Evaluation"). The
 * values are the wire codes, which is why 0 is trilinear (the first code the protocol had):
 * a caller with no preference passes SDFC_INTERP_DEFAULT, as sdfq does. */
typedef enum sdfc_interpolation {
    SDFC_INTERP_TRILINEAR = 0,
    SDFC_INTERP_NEAREST = 1,
    SDFC_INTERP_HERMITE = 2, /* first-order volumes only: a zero-order one is refused
                                (SDFC_ESERVER, 422 EINVAL) */
    SDFC_INTERP_DEFAULT = 3, /* hermite on first-order volumes, trilinear on zero-order */
} sdfc_interpolation;

/* "trilinear", "nearest", "hermite", "default": 0 or SDFC_EINVAL. */
int sdfc_interpolation_from_name(const char *name, sdfc_interpolation *out);

/* Send a VOLUME_QUERY on baked volume `volume`: `gradient` 0 answers 1 word per point (the
 * value), 1 answers 4 (value, gradient x y z), read between the nodes by `interpolation`
 * (an unknown value is SDFC_EINVAL, nothing sent). `result` needs 4 * (gradient ? 4 : 1) *
 * count bytes; otherwise as sdfc_send_query. */
int sdfc_send_volume_query(sdfc_client *c, const char *volume, int gradient,
                           sdfc_interpolation interpolation, const float *points,
                           uint32_t count, void *result, size_t result_size,
                           uint32_t *request_id);

/* Wait for the reply to `request_id` (receiving others that come first into their
 * buffers). 0: its result is in its buffer; SDFC_ESERVER: the server refused this request
 * (sdfc_server_error); SDFC_ENOREQUEST: no such request in flight (already waited for).
 * Each id is waited for once; its buffer is the caller's again after that. */
int sdfc_wait(sdfc_client *c, uint32_t request_id);

/* Wait for whichever reply is next to complete among those not yet waited for, in the order
 * replies arrive; *request_id says which. SDFC_ENOREQUEST when none is in flight. */
int sdfc_wait_any(sdfc_client *c, uint32_t *request_id);

/* Requests sent and not yet waited for. */
size_t sdfc_in_flight(const sdfc_client *c);

/* Send and wait: one query. */
int sdfc_query(sdfc_client *c, const char *mesh, sdfc_mode mode, sdfc_sign sign,
               const sdfc_filter *filter, const float *points, uint32_t count, void *result,
               size_t result_size);

#ifdef __cplusplus
}
#endif

#endif
