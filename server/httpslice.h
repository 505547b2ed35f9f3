/* httpslice.h - the slice routes, GET /v1/meshes/{name}/slice.png and
 * GET /v1/volumes/{name}/slice.png (docs/api.md, "Slices"). */
#ifndef SDFD_HTTPSLICE_H
#define SDFD_HTTPSLICE_H

#include "httpreq.h"

/* Parse the URL arguments (a refusal is 422 naming the argument), then compute, render and
 * encode on a worker thread: a mesh's points go to the batcher as one query (queries.h), a
 * volume's through sdf_volume_eval. req->route says which. */
enum MHD_Result sdfd_http_slice(sdfd_http_request *req);

#endif
