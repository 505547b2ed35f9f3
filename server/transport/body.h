/* body.h - query bodies in and out, in the three forms the HTTP API speaks:
 *   application/json          {"points": [[x,y,z],...] | [x,y,z,...], "mode": ..., "sign": ...,
 *                              "filter": {...}, "interpolation": ... (volume queries)}
 *   application/octet-stream  little-endian float32 xyz triples (parameters in the URL)
 *   application/x-npy         float32 or float64 (N, 3), or (..., 3) whose leading shape the
 *                             npy answer keeps (parameters in the URL)
 * Results always start as the wire layout of PROTOCOL.md (W 32-bit words per point, held
 * in a sdfd_reply), which is the octet-stream body as is, the npy body after a header, and
 * the source the JSON text is printed from (9 significant digits, numtext.h: every float32
 * round-trips exactly).
 *
 * The JSON reader is hand-written for the one shape it needs, because bulk float arrays are
 * the whole payload: it scans numbers straight into a float array (cJSON would build a node
 * per number). It is strict JSON all the same; other keys are parsed and ignored. */
#ifndef SDFD_BODY_H
#define SDFD_BODY_H

#include <stddef.h>
#include <stdint.h>

#include "proto.h"

typedef enum sdfd_form { SDFD_FORM_JSON, SDFD_FORM_OCTET, SDFD_FORM_NPY } sdfd_form;

/* Content-Type (parameters like "; charset=utf-8" ignored) -> form; -1 if unsupported. */
int sdfd_form_from_type(const char *content_type);
const char *sdfd_form_type(sdfd_form form);

/* The most leading dimensions of an npy points array: (a, b, c, 3) at most. */
#define SDFD_MAX_LEAD 3

/* What a request asks for. Strings point into the body or the URL; NULL = not given. */
typedef struct sdfd_query_params {
    const char *mode, *sign, *interpolation; /* interpolation: volume queries */
    size_t mode_len, sign_len, interpolation_len;
    const char *filter; /* JSON: the text of the "filter" object (filterparams.h) */
    size_t filter_len;
    /* An npy body of shape (..., 3) with more than one leading dimension: those dimensions
     * (their product is the point count), which an npy answer keeps; 0 for (N, 3). */
    size_t lead[SDFD_MAX_LEAD];
    int lead_ndim;
} sdfd_query_params;

/* Parse a query body. On success *points is either `body` itself (octet/npy float32 data,
 * aligned) or a new array the caller frees (*owned = 1). On failure returns an SDF_E* code
 * and writes a message into `err`. `body` must be NUL-terminated after `len` bytes. */
int sdfd_parse_points(sdfd_form form, char *body, size_t len, size_t max_points,
                      sdfd_query_params *params, float **points, size_t *count, int *owned,
                      char *err, size_t err_cap);

/* A reply: the wire words, with room for an npy header in front. */
typedef struct sdfd_reply {
    char *buffer;      /* malloc'd: [header][words] */
    size_t header;     /* bytes before the words (0 unless npy) */
    uint32_t *words;   /* buffer + header */
    size_t count;
    sdf_proto_mode mode;
} sdfd_reply;

/* Allocate a reply for `count` points in `mode` shaped for `form`; an npy reply has the
 * shape `lead` (lead_ndim dimensions whose product is count; 0 dimensions: (count,)), then
 * the mode's words when there are several. 0 or SDF_ENOMEM. */
int sdfd_reply_init(sdfd_reply *r, sdfd_form form, sdf_proto_mode mode, size_t count,
                    const size_t *lead, int lead_ndim);

/* Turn a filled reply into the response body; returns a malloc'd buffer (which may be
 * r->buffer itself, then owned by the caller) and its length. NULL on out-of-memory. */
char *sdfd_reply_render(sdfd_reply *r, sdfd_form form, size_t *len);

#endif
