/* error.c - names and messages of the SDF_E* codes, both generated from the single
 * SDF_ERRNO_MAP table in sdf.h so they cannot drift apart; plus the sdf_diag helper
 * that every parser uses to say where an input went wrong. */
#include "core/diag.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

const char *sdf_strerror(int err)
{
    switch (err) {
    case SDF_OK: return "success";
#define SDF__ERRNO_MSG(name, value, msg) case SDF_##name: return msg;
        SDF_ERRNO_MAP(SDF__ERRNO_MSG)
#undef SDF__ERRNO_MSG
    default: return "unknown error";
    }
}

const char *sdf_errname(int err)
{
    switch (err) {
    case SDF_OK: return "OK";
#define SDF__ERRNO_NAME(name, value, msg) case SDF_##name: return #name;
        SDF_ERRNO_MAP(SDF__ERRNO_NAME)
#undef SDF__ERRNO_NAME
    default: return "EUNKNOWN";
    }
}

int sdf__diag_set(sdf_diag *diag, int code, long line, long long offset, const char *fmt, ...)
{
    if (!diag)
        return code;
    diag->code = code;
    diag->line = line;
    diag->offset = offset;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(diag->message, sizeof diag->message, fmt, ap);
    va_end(ap);
    return code;
}

void sdf__diag_clear(sdf_diag *diag)
{
    if (!diag)
        return;
    memset(diag, 0, sizeof *diag);
    diag->offset = -1;
    snprintf(diag->message, sizeof diag->message, "%s", "success");
}
