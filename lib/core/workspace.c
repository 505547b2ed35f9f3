/* workspace.c - a caller's scratch kept between batch calls (see workspace.h). */
#include "core/workspace.h"

#include <stdatomic.h>
#include <stdlib.h>

#include "core/bigmem.h"

struct sdf_workspace {
    atomic_flag busy; /* set while a call has claimed it */
    void *array[SDF__WS_SLOTS];
    size_t bytes[SDF__WS_SLOTS]; /* what each array was asked for */
    size_t held;                 /* their sdf__big_size, summed */
};

int sdf_workspace_create(sdf_workspace **out)
{
    if (!out)
        return SDF_EINVAL;
    *out = calloc(1, sizeof **out);
    if (!*out)
        return SDF_ENOMEM;
    atomic_flag_clear(&(*out)->busy);
    return 0;
}

void sdf_workspace_destroy(sdf_workspace *ws)
{
    if (!ws)
        return;
    for (int s = 0; s < SDF__WS_SLOTS; s++)
        sdf__big_free(ws->array[s]);
    free(ws);
}

size_t sdf_workspace_bytes(const sdf_workspace *ws)
{
    return ws ? ws->held : 0;
}

const sdf_query_options *sdf__ws_enter(const sdf_query_options *opts, sdf__ws_call *call)
{
    call->claimed = NULL;
    if (!opts || !opts->workspace)
        return opts;
    if (!atomic_flag_test_and_set(&opts->workspace->busy)) {
        call->claimed = opts->workspace;
        return opts;
    }
    call->opts = *opts;
    call->opts.workspace = NULL;
    return &call->opts;
}

void sdf__ws_leave(sdf__ws_call *call)
{
    if (call->claimed)
        atomic_flag_clear(&call->claimed->busy);
    call->claimed = NULL;
}

void *sdf__ws_alloc(sdf_workspace *ws, sdf__ws_slot slot, size_t bytes)
{
    if (!ws)
        return sdf__big_alloc(bytes);
    if (ws->array[slot] && ws->bytes[slot] >= bytes)
        return ws->array[slot];
    /* Grown to what this call needs: the old contents are scratch. */
    sdf__big_free(ws->array[slot]);
    ws->held -= ws->array[slot] ? sdf__big_size(ws->bytes[slot]) : 0;
    ws->array[slot] = sdf__big_alloc(bytes);
    ws->bytes[slot] = ws->array[slot] ? bytes : 0;
    ws->held += ws->array[slot] ? sdf__big_size(bytes) : 0;
    return ws->array[slot];
}

void sdf__ws_free(sdf_workspace *ws, void *p)
{
    if (!ws)
        sdf__big_free(p);
}

size_t sdf__ws_create_bytes(void)
{
    return sizeof(struct sdf_workspace);
}
