/* httpquery.c - the HTTP spelling of the two queries (httpquery.h): the body in any form and
 * the URL's arguments into the handlers' terms (queries.h), the answer words rendered in the
 * reply form. The connection is suspended before admission, which may end on a loader's
 * thread, and resumed by the query's done callback. */
#include "transport/httpquery.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/errors.h"
#include "ops/filterparams.h"

typedef sdfd_http_request request;

/* What both queries do once their arguments are read: room for the answer in the reply
 * form, the connection suspended (admission may end on a loader's thread), then the
 * handler's admission; a refusal resumes it and answers at once. */
static enum MHD_Result submit(request *req, sdfd_form form, const sdfd_query_params *params,
                              sdf_proto_mode mode, size_t count, sdfd_http_respond respond,
                              int (*admit)(request *req, char *err, size_t cap))
{
    req->reply_form = (sdfd_form)sdfd_http_reply_form(req, form);
    if (sdfd_reply_init(&req->reply, req->reply_form, mode, count, params->lead,
                        params->lead_ndim))
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory for %zu results", count);
    req->points = count;
    sdfd_http_wait(req, respond);
    char err[SDFD_QUERY_MESSAGE_MAX];
    int rc = admit(req, err, sizeof err);
    if (rc) {
        sdfd_http_unwait(req);
        req->points = 0;
        return sdfd_http_error(req, rc, "%s", err);
    }
    return MHD_YES;
}

/* ---- mesh queries ------------------------------------------------------------------------ */

static int admit_query(request *req, char *err, size_t cap)
{
    req->query.job.words = req->reply.words;
    return sdfd_query_admit(req->srv, &req->query, err, cap);
}

static void query_done(sdfd_job *job)
{
    sdfd_http_resume(job->user);
}

static enum MHD_Result reply_query(request *req)
{
    if (req->query.refused) { /* after a load */
        req->points = 0;
        return sdfd_http_error(req, req->query.job.status, "%s", req->query.refusal);
    }
    if (req->query.job.status)
        return sdfd_http_error(req, req->query.job.status, "query failed: %s",
                               req->query.job.message);
    return sdfd_http_results(req);
}

/* The filter's parameters go with the filtered modes only: with another they would be
 * ignored, so they are refused. 0, or -1 with the refusal queued (its result in *refused). */
static int filter_misplaced(request *req, const sdfd_query_params *params, const char *mode,
                            enum MHD_Result *refused)
{
    const char *arg = sdfd_url_first_filter_arg(&req->args);
    if (params->filter)
        *refused = sdfd_http_error(req, SDF_EINVAL, "\"filter\" goes with mode filtered or "
                                   "filtered-gradient, not '%s'", mode ? mode : "signed");
    else if (arg)
        *refused = sdfd_http_refuse(req, SDF_EINVAL, arg, "'%s' is a filter parameter: it goes "
                                    "with mode=filtered or filtered-gradient, not '%s'", arg,
                                    mode ? mode : "signed");
    return params->filter || arg ? -1 : 0;
}

/* The HTTP spelling of a query (body, URL arguments, Accept) into the handler's terms. */
enum MHD_Result sdfd_http_query(request *req)
{
    sdfd_form form;
    sdfd_query_params params;
    size_t count;
    enum MHD_Result refused;
    if (sdfd_http_read_points(req, &form, &params, &count, &refused))
        return refused;
    char err[300], mode_buf[32], sign_buf[32];
    int rc;
    const char *mode = sdfd_http_param(params.mode, params.mode_len, mode_buf, sizeof mode_buf);
    const char *sign = sdfd_http_param(params.sign, params.sign_len, sign_buf, sizeof sign_buf);
    sdf_proto_mode m = SDF_MODE_SIGNED;
    sdf_sign_method s = SDF_SIGN_AUTO;
    if (mode && sdf_proto_mode_from_name(mode, &m))
        return sdfd_http_error(req, SDF_EINVAL,
                               "unknown mode '%s' (signed, distance, gradient, closest, filtered, "
                               "filtered-gradient)",
                               mode);
    if (sign && sdf_sign_from_name(sign, &s))
        return sdfd_http_error(req, SDF_EINVAL,
                               "unknown sign '%s' (auto, pseudonormal, winding, raycast, none)",
                               sign);
    if (!sdf_proto_mode_filtered(m) && filter_misplaced(req, &params, mode, &refused))
        return refused;
    sdfd_query *q = &req->query;
    *q = (sdfd_query){.mesh_name = req->name, .mesh_name_len = strlen(req->name),
                      .job = {.mode = m, .sign = s, .points = req->points_buf, .count = count,
                              .done = query_done, .user = req}};
    char volume_name[SDFD_VOLUME_NAME_MAX + 1] = "";
    if (sdf_proto_mode_filtered(m)) {
        sdf_filter_options *filter = &q->job.filter;
        rc = params.filter ? sdfd_filter_from_json(params.filter, params.filter_len, filter,
                                                   volume_name, err, sizeof err)
                           : sdfd_filter_from_strings(sdfd_url_lookup, &req->args, filter,
                                                      volume_name, err, sizeof err);
        if (rc)
            return sdfd_http_error(req, rc, "%s", err);
        if (volume_name[0])
            q->smoothing_name = volume_name, q->smoothing_name_len = strlen(volume_name);
    }
    return submit(req, form, &params, m, count, reply_query, admit_query);
}

/* ---- volume queries ---------------------------------------------------------------------- */

static int admit_volume_query(request *req, char *err, size_t cap)
{
    req->volume_query.words = req->reply.words;
    return sdfd_volume_query_admit(req->srv, &req->volume_query, err, cap);
}

static void volume_query_done(sdfd_volume_query *vq)
{
    sdfd_http_resume(vq->user);
}

static enum MHD_Result reply_volume_query(request *req)
{
    if (req->volume_query.refused) /* after a load */
        req->points = 0;
    if (req->volume_query.status)
        return sdfd_http_error(req, req->volume_query.status, "%s", req->volume_query.message);
    return sdfd_http_results(req);
}

enum MHD_Result sdfd_http_volume_query(request *req)
{
    sdfd_form form;
    sdfd_query_params params;
    size_t count;
    enum MHD_Result refused;
    if (sdfd_http_read_points(req, &form, &params, &count, &refused))
        return refused;
    char mode_buf[32], interp_buf[32];
    const char *mode = sdfd_http_param(params.mode, params.mode_len, mode_buf, sizeof mode_buf);
    const char *interp = sdfd_http_param(params.interpolation, params.interpolation_len,
                                         interp_buf, sizeof interp_buf);
    int gradient = 0;
    if (mode && strcasecmp(mode, "value") && !(gradient = !strcasecmp(mode, "gradient")))
        return sdfd_http_error(req, SDF_EINVAL, "unknown volume mode '%s' (value, gradient)", mode);
    sdfd_volume_query *vq = &req->volume_query;
    *vq = (sdfd_volume_query){.volume_name = req->name, .volume_name_len = strlen(req->name),
                              .interpolation = SDF_VOLUME_DEFAULT, .gradient = gradient,
                              .points = req->points_buf, .count = count,
                              .done = volume_query_done, .user = req};
    if (interp && sdf_volume_filter_from_name(interp, &vq->interpolation))
        return sdfd_http_error(req, SDF_EINVAL, "unknown interpolation '%s' (default, trilinear, "
                               "nearest, hermite)", interp);
    return submit(req, form, &params, gradient ? SDF_MODE_GRADIENT : SDF_MODE_SIGNED, count,
                  reply_volume_query, admit_volume_query);
}
