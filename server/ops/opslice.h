/* opslice.h - a slice of a mesh's or a volume's field as a picture or an npy array
 * (docs/api.md, "Slices"): GET /v1/meshes/{name}/slice.png and
 * GET /v1/volumes/{name}/slice.png. A handler of call.h; asynchronous. */
#ifndef SDFD_OPSLICE_H
#define SDFD_OPSLICE_H

#include "ops/call.h"

int sdfd_op_slice(sdfd_call *call);

#endif
