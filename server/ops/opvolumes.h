/* opvolumes.h - the operations on baked volumes as items (docs/api.md, "Volumes"): list,
 * describe, upload (an EXR, parsed on a worker thread; opitems.h deletes) and the download of a
 * volume's data (npy and raw streamed from the stored volume, EXR encoded on a worker
 * thread), all through the cache (cache.h). Handlers of call.h. */
#ifndef SDFD_OPVOLUMES_H
#define SDFD_OPVOLUMES_H

#include "ops/call.h"

int sdfd_op_volume_list(sdfd_call *call);   /* GET /v1/volumes */
int sdfd_op_volume_get(sdfd_call *call);    /* GET /v1/volumes/{name} */
int sdfd_op_volume_put(sdfd_call *call);    /* PUT /v1/volumes/{name}: asynchronous */
int sdfd_op_volume_data(sdfd_call *call);   /* GET /v1/volumes/{name}/data: asynchronous */

#endif
