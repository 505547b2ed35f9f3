/* admission.h - what every operation passes once, whichever transport asked for it: who may
 * call it (the --token rule of its line in optable.c), whether sdfd takes work now (loading,
 * draining), and, when it is answered, its count in /metrics and its line in the log. The
 * transports (http.c, binrequests.c) verify the credential in their own spelling (a bearer
 * header; an AUTH frame on the connection) and call these; nothing here knows either. */
#ifndef SDFD_ADMISSION_H
#define SDFD_ADMISSION_H

#include <stddef.h>

#include "ops/optable.h"
#include "state/server.h"

/* Whether `op` needs the --token under this configuration. */
int sdfd_needs_token(const sdfd_config *cfg, const sdfd_op *op);

/* 0 when `op` may run now; SDFD_EUNAUTHORIZED when it needs the token and the caller did not
 * present it (`token_ok`: the transport verified it); SDFD_EUNAVAILABLE with the reason in
 * msg while sdfd loads or drains (unless the operation is SDFD_OP_ALWAYS). */
int sdfd_admit(sdfd_server *srv, const sdfd_op *op, int token_ok, char *msg, size_t cap);

/* An answered request: its metrics (by op's label over the transport; op NULL: matched
 * nothing) and, unless the operation is SDFD_OP_UNLOGGED, its log line. `what` is the HTTP
 * method or the binary frame's name; `start` from sdfd_now(). */
typedef struct sdfd_answered {
    const sdfd_op *op;
    int binary;
    const char *what;
    int status;
    size_t points;
    double start;
    size_t bytes_in, bytes_out;
} sdfd_answered;
void sdfd_account(sdfd_server *srv, const sdfd_answered *a);

#endif
