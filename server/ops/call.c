/* call.c - results and the worker handover the handlers share (call.h). */
#include "ops/call.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"

void sdfd_call_release(sdfd_call *call)
{
    sdfd_result *r = &call->result;
    cJSON_Delete(r->json);
    free(r->bytes);
    sdfd_volume_release(r->stream);
    *r = (sdfd_result){0};
    free(call->state);
    call->state = NULL;
    if (call->reserved)
        sdfd_buffer_release(call->srv, call->reserved);
    call->reserved = 0;
}

int sdfd_call_fail(sdfd_call *call, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(call->result.message, sizeof call->result.message, fmt, ap);
    va_end(ap);
    call->result.code = code;
    call->result.status = sdfd_http_status(code);
    return SDFD_CALL_READY;
}

int sdfd_call_json(sdfd_call *call, int status, cJSON *json)
{
    if (!json)
        return sdfd_call_fail(call, SDF_ENOMEM, "out of memory");
    call->result.status = status;
    call->result.json = json;
    return SDFD_CALL_READY;
}

void *sdfd_call_lookup(sdfd_call *call, sdfd_item_kind kind, const char *name)
{
    void *item = NULL;
    char msg[512];
    int rc = sdfd_cache_get(call->srv->cache, kind, name, strlen(name), &item, msg, sizeof msg);
    if (rc)
        sdfd_call_fail(call, rc, "%s", msg);
    return rc ? NULL : item;
}

void sdfd_call_field(sdfd_call *call, const char *name, const char *fmt, ...)
{
    sdfd_result *r = &call->result;
    if (r->n_fields == SDFD_RESULT_FIELDS)
        return;
    sdfd_field *f = &r->fields[r->n_fields++];
    f->name = name;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(f->value, sizeof f->value, fmt, ap);
    va_end(ap);
}

static void run_work(void *arg)
{
    sdfd_call *call = arg;
    call->work(call);
    call->done(call);
}

int sdfd_call_defer(sdfd_call *call, void (*work)(sdfd_call *call))
{
    call->work = work;
    if (sdfd_workers_run(call->srv->workers, run_work, call))
        return sdfd_call_fail(call, SDFD_EUNAVAILABLE, "cannot start a worker thread");
    return SDFD_CALL_PENDING;
}
