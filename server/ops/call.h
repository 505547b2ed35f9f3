/* call.h - one operation called, whichever transport asked: its inputs as plain values (the
 * name in its path, its URL arguments, its body), and its answer as a result (a status and
 * a JSON document, bytes, a volume to stream, or an error with its code, message and the
 * argument at fault). The handlers (opmeshes.c, opvolumes.c, opjobs.c, opslice.c,
 * opstatus.c) fill results and know nothing of HTTP or frames; a transport turns a request
 * into a call, runs it (sdfd_dispatch, dispatch.h), and writes the result in its own
 * spelling.
 *
 * Queries are not calls: their points go to the batcher in the transport's own buffers
 * (queries.h), so that nothing is copied on the hot path.
 *
 * Operations flagged SDFD_OP_ASYNC in optable.c may finish on a worker thread: the transport
 * must be ready to be called back (HTTP suspends the connection) before sdfd_dispatch, which
 * then returns SDFD_CALL_PENDING and calls `done` once, from the worker. */
#ifndef SDFD_CALL_H
#define SDFD_CALL_H

#include <cjson/cJSON.h>
#include <stddef.h>

#include "ops/optable.h"
#include "ops/urlargs.h"
#include "state/server.h"

#define SDFD_RESULT_FIELDS 6

/* A named field of an answer beyond its body (HTTP sends them as headers). */
typedef struct sdfd_field {
    const char *name;
    char value[300];
} sdfd_field;

typedef struct sdfd_result {
    int status;             /* 200, 201, 202 or 204 when code is 0 */
    int code;               /* 0, or the SDF_E* / SDFD_E* that refused the call */
    char message[512];      /* with a code: what the client is told */
    const char *argument;   /* with a code: the URL argument at fault, or NULL */
    cJSON *json;            /* the answer as JSON, or NULL */
    char *bytes;            /* or the answer as bytes (malloc'd) of `type` */
    size_t len;
    const char *type;
    sdfd_stored_volume *stream; /* or a volume's node words, retained, as `file` (npy, raw) */
    sdf_volume_file file;
    sdfd_field fields[SDFD_RESULT_FIELDS];
    int n_fields;
} sdfd_result;

typedef struct sdfd_call sdfd_call;

struct sdfd_call {
    /* in, from the transport; read-only for the handler, valid until sdfd_call_release */
    sdfd_server *srv;
    const sdfd_op *op;
    const char *name;            /* the path's parameter ("" when it has none) */
    const sdfd_url_args *args;   /* checked against the operation's (urlargs.h) */
    const char *body;            /* NUL-terminated, len bytes; NULL when none */
    size_t len;
    void (*done)(sdfd_call *call); /* SDFD_CALL_PENDING only: on the worker's thread */
    void *user;
    /* out */
    sdfd_result result;
    size_t points;               /* points the answer computed, for the log */
    /* the handler's, freed by sdfd_call_release */
    size_t reserved;             /* bytes of --max-buffered-bytes held */
    void *state;
    void (*work)(sdfd_call *call);
};

/* What a handler (and sdfd_dispatch, dispatch.h) returns. */
enum { SDFD_CALL_READY = 0, SDFD_CALL_PENDING = 1 };

/* Free what the result and the handler hold. */
void sdfd_call_release(sdfd_call *call);

/* ---- for the handlers ---- */

/* Refuse: the code, its message, no argument. Returns SDFD_CALL_READY. */
int sdfd_call_fail(sdfd_call *call, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* Answer with JSON (taken over) and a status. Returns SDFD_CALL_READY. */
int sdfd_call_json(sdfd_call *call, int status, cJSON *json);
/* The item of `kind` called `name` through the cache (sdfd_cache_get, which may wait for a
 * load from the store): a retained reference (an sdf_mesh * or an sdfd_stored_volume *), or
 * NULL with the call refused by the lookup's code and message. */
void *sdfd_call_lookup(sdfd_call *call, sdfd_item_kind kind, const char *name);
/* Add a named field to the answer. */
void sdfd_call_field(sdfd_call *call, const char *name, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* Run `work` on a worker thread, then call->done. SDFD_CALL_PENDING, or SDFD_CALL_READY with
 * a refusal when no thread could be started (work does not run). */
int sdfd_call_defer(sdfd_call *call, void (*work)(sdfd_call *call));

#endif
