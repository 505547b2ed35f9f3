/* opitems.h - what the mesh and volume operations share, whichever kind of item the path
 * names: deletion through the cache (the store first, then memory). A handler of call.h. */
#ifndef SDFD_OPITEMS_H
#define SDFD_OPITEMS_H

#include "ops/call.h"

/* DELETE /v1/meshes/{name} and DELETE /v1/volumes/{name}. */
int sdfd_op_delete(sdfd_call *call);

#endif
