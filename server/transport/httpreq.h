/* httpreq.h - one HTTP request's state and how to answer it: the responses (an operation's
 * result, call.h, in HTTP's spelling), the query-body helpers and the wait for work done
 * elsewhere. Used by http.c (admission, calls and MHD's callbacks) and httpquery.c (the
 * queries), which call it and never the reverse. */
#ifndef SDFD_HTTPREQ_H
#define SDFD_HTTPREQ_H

#include <cjson/cJSON.h>
#include <microhttpd.h>
#include <stdatomic.h>

#include "ops/call.h"
#include "ops/optable.h"
#include "ops/queries.h"
#include "ops/urlargs.h"
#include "state/server.h"
#include "transport/body.h"

typedef struct sdfd_http_request sdfd_http_request;
typedef enum MHD_Result (*sdfd_http_respond)(sdfd_http_request *req);

/* A response header beyond the type and count: a result's field. */
typedef sdfd_field sdfd_http_header;

struct sdfd_http_request {
    sdfd_server *srv;
    struct MHD_Connection *conn;
    const char *method;
    const sdfd_op *op;            /* what it asks for; NULL until admission matched one */
    char name[SDFD_MAX_NAME + 1]; /* mesh or volume name, or job id, from the URL */
    sdfd_url_args args;           /* the URL's arguments, checked at admission (urlargs.h) */
    double start;
    int answered;                 /* a response is queued */
    int status;
    size_t points, bytes_out;
    /* body */
    char *body;
    size_t len, declared;
    size_t reserved;         /* of the server's --max-buffered-bytes, released at completion */
    /* work done elsewhere (sdfd_http_wait): `respond` answers once the worker has set
     * `finished` and resumed the connection */
    int waiting;
    atomic_int finished;
    sdfd_http_respond respond;
    sdfd_query query;             /* a mesh query's; its references released at completion */
    sdfd_volume_query volume_query;
    float *points_buf;
    int points_owned;
    sdfd_form reply_form;
    sdfd_reply reply;
    sdfd_call call;               /* an operation's other than a query (call.h) */
};

/* ---- responses ---- */

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
/* The same, naming the URL argument it is about in "argument" (none when it is NULL or ""). */
enum MHD_Result sdfd_http_refuse(sdfd_http_request *req, int code, const char *argument,
                                 const char *fmt, ...) __attribute__((format(printf, 4, 5)));
/* The filled req->reply in the reply form, with the point count in X-SDF-Count. */
enum MHD_Result sdfd_http_results(sdfd_http_request *req);
/* An operation's result: its refusal, or its JSON, bytes (taken over) or streamed volume
 * with its fields as headers. */
enum MHD_Result sdfd_http_result(sdfd_http_request *req, sdfd_result *r);

/* ---- URL arguments ---- */

/* Collect the URL's arguments into req->args (repeats and all) and check them against the
 * route's table (urlargs.h). 0, or -1 with the refusal queued and its MHD result in
 * *refused. Admission calls it for every request, before the route acts. */
int sdfd_http_check_args(sdfd_http_request *req, enum MHD_Result *refused);

/* ---- query bodies ---- */

/* A query parameter's text (from sdfd_http_read_points) copied into buf, or NULL. */
const char *sdfd_http_param(const char *value, size_t n, char *buf, size_t cap);
/* The form to answer in: Accept's, else the request's. */
int sdfd_http_reply_form(sdfd_http_request *req, sdfd_form request_form);
/* Parse a query body of any form into req->points_buf, and its parameters into *params:
 * a JSON body's keys, else the URL's arguments. A parameter given in both, a JSON key of the
 * other query route (a mesh query's "interpolation", a volume query's "sign" or "filter"), or
 * a "filter" with the filter's URL arguments, is refused. Returns 0, or -1 with the error
 * queued and its MHD result in *refused. */
int sdfd_http_read_points(sdfd_http_request *req, sdfd_form *form, sdfd_query_params *params,
                          size_t *count, enum MHD_Result *refused);

/* ---- work done elsewhere ---- */

/* Suspend the connection before handing work over (so the resume cannot come first);
 * `respond` answers once the worker has called sdfd_http_resume. */
void sdfd_http_wait(sdfd_http_request *req, sdfd_http_respond respond);
/* The handover failed: resume at once, to answer now. */
void sdfd_http_unwait(sdfd_http_request *req);
/* The worker's last word on the request: any thread. */
void sdfd_http_resume(sdfd_http_request *req);

#endif
