/* errors.h - sdfd's error codes: the library's SDF_E* codes (sdf.h) extended by the ones only
 * a network server has (auth, methods, lengths, load, shutdown, request syntax, a full store)
 * and the binary protocol's SDF_EPROTO (proto.h), and the HTTP status every code is answered
 * with.
 *
 * Clients see these as the `code` name and status of an HTTP error body and of a binary
 * ERROR frame (docs/api.md, proto/PROTOCOL.md), so names, values and statuses stay as they
 * are. The server's values fill the gap the library leaves (-13..-19) and go on past the
 * library's last (-21 on); sdfd_errname's switch over both tables fails to compile on a value
 * used twice. */
#ifndef SDFD_ERRORS_H
#define SDFD_ERRORS_H

#include "proto.h"
#include "sdf/sdf.h"

/* X(NAME, value, http_status, message); the enum is SDFD_<NAME>. */
#define SDFD_ERRNO_MAP(X)                                                                 \
    X(EPROTO, -13, 400, "protocol error")                                                 \
    X(EUNAUTHORIZED, -14, 401, "missing or wrong bearer token")                           \
    X(EMETHOD, -15, 405, "method not allowed")                                            \
    X(ELENGTH, -16, 411, "Content-Length required")                                       \
    X(EBUSY, -17, 429, "too many requests")                                               \
    X(EUNAVAILABLE, -18, 503, "service unavailable (loading or shutting down)")           \
    X(ESYNTAX, -19, 400, "malformed request")                                             \
    X(ENOSPACE, -21, 507, "the store is full")

/* X(NAME, http_status) for every code of the library's SDF_ERRNO_MAP. A library code without
 * a line here fails to compile in errors.c (SDFD_STATUS_<NAME> undeclared): add its line. */
#define SDFD_LIBRARY_STATUS_MAP(X)                                                        \
    X(EINVAL, 422) X(ENOMEM, 503) X(EIO, 500) X(EFORMAT, 415) X(EPARSE, 422)              \
    X(ETRUNC, 422) X(ELIMIT, 413) X(EEMPTY, 422) X(ENONFINITE, 422) X(EINDEX, 422)        \
    X(EBVH, 500) X(ENOTFOUND, 404) X(ECANCELED, 409)

typedef enum sdfd_error {
#define SDFD__ERRNO_ENUM(name, value, http, msg) SDFD_##name = (value),
    SDFD_ERRNO_MAP(SDFD__ERRNO_ENUM)
#undef SDFD__ERRNO_ENUM
} sdfd_error;

_Static_assert(SDFD_EPROTO == SDF_EPROTO, "the codec's SDF_EPROTO is the server's EPROTO");

/* What sdf_strerror, sdf_errname give for the library's codes and SDF_OK, extended to the
 * server's; "unknown error" and "EUNKNOWN" for any other value. */
const char *sdfd_strerror(int err);
const char *sdfd_errname(int err);
/* The HTTP status that reports the code (200 for SDF_OK, 500 for unknown codes); a binary
 * ERROR frame carries the same. */
int sdfd_http_status(int err);

#endif
