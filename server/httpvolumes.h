/* httpvolumes.h - the HTTP routes of baked volumes (httpvolumes.c; docs/api.md, "Volumes"),
 * which http.c dispatches to. */
#ifndef SDFD_HTTPVOLUMES_H
#define SDFD_HTTPVOLUMES_H

#include "httpreq.h"

enum MHD_Result sdfd_http_bake(sdfd_http_request *req);         /* POST /v1/meshes/{name}/bake */
enum MHD_Result sdfd_http_volume_ops(sdfd_http_request *req);   /* POST /v1/volumes/{name}/ops */
enum MHD_Result sdfd_http_jobs(sdfd_http_request *req);         /* GET /v1/jobs */
enum MHD_Result sdfd_http_job(sdfd_http_request *req);          /* GET, DELETE /v1/jobs/{id} */
enum MHD_Result sdfd_http_volumes(sdfd_http_request *req);      /* GET /v1/volumes */
enum MHD_Result sdfd_http_volume(sdfd_http_request *req);       /* GET, PUT, DELETE .../{name} */
enum MHD_Result sdfd_http_volume_data(sdfd_http_request *req);  /* GET .../{name}/data */
enum MHD_Result sdfd_http_volume_query(sdfd_http_request *req); /* POST .../{name}/query */

#endif
