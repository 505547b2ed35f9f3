/* opitems.c - deletion of a mesh or a volume (opitems.h). */
#include "ops/opitems.h"

#include "core/log.h"

int sdfd_op_delete(sdfd_call *call)
{
    int volume = call->op->id == SDFD_OP_VOLUME_DELETE;
    char msg[512];
    int rc = sdfd_cache_remove(call->srv->cache, volume ? SDFD_ITEM_VOLUME : SDFD_ITEM_MESH,
                               call->name, msg, sizeof msg);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", msg);
    sdfd_log("info", volume ? "volume_deleted" : "mesh_deleted", "%s", call->name);
    call->result.status = 204;
    return SDFD_CALL_READY;
}
