/* opextract.h - a volume's surface as a mesh (docs/api.md, "Meshes from volumes"): GET
 * answers it as a file (PLY, OBJ, STL or OFF), POST stores it as a mesh of its own. Both
 * extract on a worker thread (sdf_volume_extract, on --threads threads). Handlers of call.h. */
#ifndef SDFD_OPEXTRACT_H
#define SDFD_OPEXTRACT_H

#include "ops/call.h"

int sdfd_op_volume_mesh(sdfd_call *call);      /* GET /v1/volumes/{name}/mesh */
int sdfd_op_volume_mesh_post(sdfd_call *call); /* POST /v1/volumes/{name}/mesh */

#endif
