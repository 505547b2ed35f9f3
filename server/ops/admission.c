/* admission.c - the checks and the accounting every operation shares (admission.h). */
#include "ops/admission.h"

#include <stdio.h>

#include "core/errors.h"
#include "core/log.h"

int sdfd_needs_token(const sdfd_config *cfg, const sdfd_op *op)
{
    return cfg->token && (op->auth == SDFD_AUTH_WRITE ||
                          (op->auth == SDFD_AUTH_QUERY && cfg->auth_queries));
}

int sdfd_admit(sdfd_server *srv, const sdfd_op *op, int token_ok, char *msg, size_t cap)
{
    if (sdfd_needs_token(&srv->cfg, op) && !token_ok) {
        snprintf(msg, cap, "%s needs the server's token", op->name);
        return SDFD_EUNAUTHORIZED;
    }
    const char *unavailable = op->flags & SDFD_OP_ALWAYS ? NULL : sdfd_unavailable(srv);
    if (unavailable) {
        snprintf(msg, cap, "%s", unavailable);
        return SDFD_EUNAVAILABLE;
    }
    return 0;
}

void sdfd_account(sdfd_server *srv, const sdfd_answered *a)
{
    double seconds = sdfd_now() - a->start;
    sdfd_metrics_request(srv->metrics, sdfd_op_label_index(a->op, a->binary), a->status, seconds);
    if (a->op && (a->op->flags & SDFD_OP_UNLOGGED))
        return;
    const char *route = !a->op ? "other" : a->binary ? a->op->name : a->op->path;
    sdfd_log_request(a->binary ? "binary" : "http", a->what, route, a->status, a->points,
                     seconds * 1e6, a->bytes_in, a->bytes_out);
}
