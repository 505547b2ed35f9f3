/* httpreq.h - what the two halves of the HTTP front end share (http.c: admission, mesh
 * queries and uploads, MHD callbacks; httpvolumes.c: bakes, jobs and volumes): the state of
 * one request and the helpers that answer it. Not used outside those two files. */
#ifndef SDFD_HTTPREQ_H
#define SDFD_HTTPREQ_H

#include <cjson/cJSON.h>
#include <microhttpd.h>
#include <stdatomic.h>

#include "body.h"
#include "http.h"

struct sdfd_http {
    sdfd_server *srv;
    struct MHD_Daemon *daemon;
    int listen_fd;
    int quiesced; /* listen_fd handed back by MHD_quiesce_daemon: ours to close */
};

/* Work a request waits for: a batcher job, or a thread of its own running `run` (uploads,
 * volume queries and file encodings: not geometry for the batcher, but too slow for MHD's
 * I/O threads). */
typedef enum sdfd_http_wait { WORK_NONE, WORK_QUERY, WORK_THREAD } sdfd_http_wait;

typedef struct sdfd_http_request sdfd_http_request;
typedef void (*sdfd_http_work)(sdfd_http_request *req);

/* A response header beyond the type and count. */
typedef struct sdfd_http_header {
    const char *name;
    char value[300];
} sdfd_http_header;

struct sdfd_http_request {
    sdfd_http *http;
    struct MHD_Connection *conn;
    const char *method;
    sdfd_route route;
    char route_text[96];
    char name[SDFD_MAX_NAME + 1]; /* mesh or volume name, or job id, from the URL */
    double start;
    int answered;                 /* a response is queued */
    int status;
    size_t points, bytes_out;
    /* body */
    char *body;
    size_t len, declared;
    size_t reserved;         /* of the server's --max-buffered-bytes, released at completion */
    /* background work; `finished` is set by the worker before it resumes the connection */
    sdfd_http_wait work;
    atomic_int finished;
    sdfd_job job;
    float *points_buf;
    int points_owned;
    sdfd_form reply_form;
    sdfd_reply reply;
    char format[16];              /* ?format= of an upload, copied on the MHD thread */
    sdf_mesh *uploaded;
    sdf_mesh *volume; /* a filtered query's smoothing mesh, held until the request ends */
    int work_rc, replaced;        /* a thread's result: 0 or SDF_E* (message in diag) */
    sdf_diag diag;
    /* WORK_THREAD: `run` leaves a status (0 or SDF_E*, message in diag) and a body */
    sdfd_http_work run;
    enum MHD_Result (*respond)(
        sdfd_http_request *req);  /* back on the MHD thread: queue the response */
    sdfd_stored_volume *stored;   /* a volume query's or download's volume */
    sdf_volume_filter interpolation;
    sdf_volume_file file_type;
    char *out_body;
    size_t out_len;
};

/* ---- responses (http.c) ---- */

/* Queue response r (len bytes) with the type, the extra headers and the route's usual ones. */
enum MHD_Result sdfd_http_queue(sdfd_http_request *req, int status, const char *type,
                                struct MHD_Response *r, size_t len, const sdfd_http_header *extra,
                                int n_extra);
/* A malloc'd body (freed by MHD) with extra headers. */
enum MHD_Result sdfd_http_send(sdfd_http_request *req, int status, const char *type, char *body,
                               size_t len, const sdfd_http_header *extra, int n_extra);
/* A malloc'd body, with the point count in X-SDF-Count when `count` is not NULL. */
enum MHD_Result sdfd_http_buffer(sdfd_http_request *req, int status, const char *type, char *body,
                                 size_t len, const char *count);
/* Print and delete `json`, then send it. */
enum MHD_Result sdfd_http_json(sdfd_http_request *req, int status, cJSON *json);
/* {"error": {"code": "ENOTFOUND", "message": "..."}} with the code's HTTP status. */
enum MHD_Result sdfd_http_error(sdfd_http_request *req, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* The filled req->reply in the reply form, with the point count in X-SDF-Count. */
enum MHD_Result sdfd_http_results(sdfd_http_request *req);

/* ---- query bodies (http.c) ---- */

/* A parameter from the body (JSON) or else the URL query string. */
const char *sdfd_http_param(sdfd_http_request *req, const char *body_value, size_t n,
                            const char *key, char *buf, size_t cap);
/* The form to answer in: Accept's, else the request's. */
int sdfd_http_reply_form(sdfd_http_request *req, sdfd_form request_form);
/* Parse a query body of any form into req->points_buf. Returns 0, or -1 with the error
 * queued and its MHD result in *refused. */
int sdfd_http_read_points(sdfd_http_request *req, sdfd_form *form, sdfd_query_params *params,
                          size_t *count, enum MHD_Result *refused);

/* Suspend the connection and run `run` on a new thread; `respond` answers after the resume. */
enum MHD_Result sdfd_http_start_thread(sdfd_http_request *req, sdfd_http_work run,
                                       enum MHD_Result (*respond)(sdfd_http_request *req));

/* ---- the volume routes (httpvolumes.c) ---- */

enum MHD_Result sdfd_http_bake(sdfd_http_request *req);         /* POST /v1/meshes/{name}/bake */
enum MHD_Result sdfd_http_jobs(sdfd_http_request *req);         /* GET /v1/jobs */
enum MHD_Result sdfd_http_job(sdfd_http_request *req);          /* GET, DELETE /v1/jobs/{id} */
enum MHD_Result sdfd_http_volumes(sdfd_http_request *req);      /* GET /v1/volumes */
enum MHD_Result sdfd_http_volume(sdfd_http_request *req);       /* GET, PUT, DELETE .../{name} */
enum MHD_Result sdfd_http_volume_data(sdfd_http_request *req);  /* GET .../{name}/data */
enum MHD_Result sdfd_http_volume_query(sdfd_http_request *req); /* POST .../{name}/query */

#endif
