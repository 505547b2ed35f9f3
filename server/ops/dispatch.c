/* dispatch.c - the handler of each operation (dispatch.h), indexed by its id. */
#include "ops/dispatch.h"

#include "core/errors.h"
#include "ops/opextract.h"
#include "ops/opitems.h"
#include "ops/opjobs.h"
#include "ops/opmeshes.h"
#include "ops/opslice.h"
#include "ops/opstatus.h"
#include "ops/opvolumes.h"

static int (*const handlers[SDFD_OP_COUNT])(sdfd_call *call) = {
    [SDFD_OP_HEALTH] = sdfd_op_health,
    [SDFD_OP_READY] = sdfd_op_ready,
    [SDFD_OP_METRICS] = sdfd_op_metrics,
    [SDFD_OP_OPENAPI] = sdfd_op_openapi,
    [SDFD_OP_MESH_LIST] = sdfd_op_mesh_list,
    [SDFD_OP_MESH_GET] = sdfd_op_mesh_get,
    [SDFD_OP_MESH_PUT] = sdfd_op_mesh_put,
    [SDFD_OP_MESH_DELETE] = sdfd_op_delete,
    [SDFD_OP_BAKE] = sdfd_op_bake,
    [SDFD_OP_MESH_SLICE] = sdfd_op_slice,
    [SDFD_OP_JOB_LIST] = sdfd_op_job_list,
    [SDFD_OP_JOB_GET] = sdfd_op_job_get,
    [SDFD_OP_JOB_CANCEL] = sdfd_op_job_cancel,
    [SDFD_OP_VOLUME_LIST] = sdfd_op_volume_list,
    [SDFD_OP_VOLUME_GET] = sdfd_op_volume_get,
    [SDFD_OP_VOLUME_PUT] = sdfd_op_volume_put,
    [SDFD_OP_VOLUME_DELETE] = sdfd_op_delete,
    [SDFD_OP_VOLUME_DATA] = sdfd_op_volume_data,
    [SDFD_OP_VOLUME_OPS] = sdfd_op_volume_ops,
    [SDFD_OP_VOLUME_SLICE] = sdfd_op_slice,
    [SDFD_OP_VOLUME_MESH] = sdfd_op_volume_mesh,
    [SDFD_OP_VOLUME_MESH_POST] = sdfd_op_volume_mesh_post,
};

int sdfd_dispatches(const sdfd_op *op)
{
    return handlers[op->id] != NULL;
}

int sdfd_dispatch(sdfd_call *call)
{
    if (!handlers[call->op->id])
        return sdfd_call_fail(call, SDF_ENOTFOUND, "%s is not an operation of calls",
                              call->op->name);
    return handlers[call->op->id](call);
}
