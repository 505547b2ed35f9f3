/* opmeshes.h - the mesh operations (docs/api.md, "Meshes"): list, describe, upload (parsed
 * and indexed on a worker thread) and delete, through the cache (cache.h), so a mesh the
 * store holds but memory does not is found. Handlers of call.h. */
#ifndef SDFD_OPMESHES_H
#define SDFD_OPMESHES_H

#include "ops/call.h"

int sdfd_op_mesh_list(sdfd_call *call);   /* GET /v1/meshes */
int sdfd_op_mesh_get(sdfd_call *call);    /* GET /v1/meshes/{name} */
int sdfd_op_mesh_put(sdfd_call *call);    /* PUT /v1/meshes/{name}: asynchronous */

/* A mesh's description: its library report (sdf_mesh_get_report) in JSON, named `name`. */
cJSON *sdfd_mesh_report_json(const char *name, const sdf_mesh *mesh);

#endif
