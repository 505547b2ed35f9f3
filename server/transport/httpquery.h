/* httpquery.h - POST /v1/meshes/{name}/query and POST /v1/volumes/{name}/query over HTTP
 * (docs/api.md, "Queries"): admitted like a binary QUERY or VOLUME_QUERY frame, through the
 * query handlers (queries.h). */
#ifndef SDFD_HTTPQUERY_H
#define SDFD_HTTPQUERY_H

#include "transport/httpreq.h"

enum MHD_Result sdfd_http_query(sdfd_http_request *req);
enum MHD_Result sdfd_http_volume_query(sdfd_http_request *req);

#endif
