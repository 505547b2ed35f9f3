/* httpslice.c - slice images of meshes and volumes (see httpslice.h).
 *
 * The arguments are read on MHD's thread (only it may look at the connection) into the
 * request's route_state; everything after runs on a worker thread of its own, like an
 * upload: the slice's pixel centres are one query handed to the batcher through the same
 * admission as any HTTP or binary query (queries.h), and the worker waits for its answer,
 * then colours and encodes it. The memory a slice holds while it is computed (points,
 * answers, picture) is counted against --max-buffered-bytes, as request bodies are. */
#include "httpslice.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "errors.h"
#include "pngenc.h"
#include "slice.h"
#include "slicerender.h"

typedef sdfd_http_request request;

typedef struct slice_work {
    sdfd_slice_params params;
    const char *argument;     /* a refusal's argument, or "" */
    /* the worker's results, read after the resume */
    sdfd_slice_plane plane;
    sdfd_slice_scale scale;
} slice_work;

/* ---- the answer --------------------------------------------------------------------------- */

static void vector_header(sdfd_http_header *h, const char *name, const double *v)
{
    h->name = name;
    snprintf(h->value, sizeof h->value, "%.9g,%.9g,%.9g", v[0], v[1], v[2]);
}

static enum MHD_Result reply_slice(request *req)
{
    slice_work *w = req->route_state;
    if (req->work_rc)
        return sdfd_http_refuse(req, req->work_rc, w->argument, "%s", req->diag.message);
    const sdfd_slice_plane *p = &w->plane;
    const sdfd_slice_scale *s = &w->scale;
    sdfd_http_header h[6] = {{"X-SDF-Slice-Size", ""}, {"X-SDF-Slice-Range", ""},
                             {"X-SDF-Slice-Step", ""}};
    snprintf(h[0].value, sizeof h[0].value, "%zu,%zu", p->width, p->height);
    snprintf(h[1].value, sizeof h[1].value, "%.9g,%.9g", s->min, s->max);
    snprintf(h[2].value, sizeof h[2].value, "%.9g", s->step);
    vector_header(&h[3], "X-SDF-Slice-First", p->first);
    vector_header(&h[4], "X-SDF-Slice-Right", p->right);
    vector_header(&h[5], "X-SDF-Slice-Down", p->down);
    char *body = req->out_body;
    req->out_body = NULL; /* MHD frees it */
    req->points = p->width * p->height;
    return sdfd_http_send(req, 200, w->params.npy ? "application/x-npy" : "image/png", body,
                          req->out_len, h, 6);
}

/* ---- the worker --------------------------------------------------------------------------- */

typedef struct waiter {
    pthread_mutex_t lock;
    pthread_cond_t cond;
    int done;
} waiter;

static void job_done(sdfd_job *job)
{
    waiter *wt = job->user;
    pthread_mutex_lock(&wt->lock);
    wt->done = 1;
    pthread_cond_signal(&wt->cond);
    pthread_mutex_unlock(&wt->lock);
}

static int fail(request *req, int rc, const char *fmt, const char *detail)
{
    snprintf(req->diag.message, sizeof req->diag.message, fmt, detail);
    return req->work_rc = rc;
}

/* The mesh `name` at `count` points through the batcher, as one query: values[i] is the
 * distance, or with `magnitude` the gradient's length. */
static int query_mesh(request *req, const char *name, sdf_proto_mode mode,
                      const sdfd_slice_params *p, const float *points, size_t count,
                      int magnitude, float *values)
{
    unsigned per = sdf_proto_words(mode);
    uint32_t *words = malloc(count * per * sizeof *words);
    if (!words)
        return fail(req, SDF_ENOMEM, "out of memory for %s", "the slice's answers");
    waiter wt = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, 0};
    sdfd_query q = {.mesh_name = name, .mesh_name_len = strlen(name),
                    .job = {.mode = mode, .sign = p->sign, .points = points, .count = count,
                            .words = words, .done = job_done, .user = &wt}};
    if (sdf_proto_mode_filtered(mode)) {
        q.job.filter = p->filter;
        if (p->smoothing_mesh[0])
            q.smoothing_name = p->smoothing_mesh, q.smoothing_name_len = strlen(p->smoothing_mesh);
    }
    char err[300];
    int rc = sdfd_query_admit(req->srv, &q, err, sizeof err);
    if (!rc) { /* admitted (perhaps after a load from the store): done will come */
        pthread_mutex_lock(&wt.lock);
        while (!wt.done)
            pthread_cond_wait(&wt.cond, &wt.lock);
        pthread_mutex_unlock(&wt.lock);
        rc = q.job.status;
        snprintf(err, sizeof err, "%s", q.refused ? q.refusal : q.job.message);
    }
    sdfd_query_release(&q); /* nothing held after a refused admission */
    for (size_t i = 0; !rc && i < count; i++) {
        float g[4];
        memcpy(g, words + (size_t)per * i, per * sizeof(float));
        values[i] = magnitude ? sqrtf(g[1] * g[1] + g[2] * g[2] + g[3] * g[3]) : g[0];
    }
    free(words);
    return rc ? fail(req, rc, "%.250s", err) : 0;
}

static int slice_mesh(request *req, slice_work *w, const float *points, size_t n, float *values)
{
    static const sdf_proto_mode modes[] = {SDF_MODE_SIGNED, SDF_MODE_DISTANCE,
                                           SDF_MODE_FILTERED, SDF_MODE_GRADIENT};
    sdfd_slice_mode m = w->params.mode;
    return query_mesh(req, req->name, modes[m], &w->params, points, n,
                      m == SDFD_SLICE_GRADIENT, values);
}

static int slice_volume(request *req, slice_work *w, const sdfd_stored_volume *s,
                        const float *points, size_t n, float *values)
{
    sdfd_slice_mode m = w->params.mode;
    sdf_volume_info in;
    sdf_volume_get_info(s->volume, &in);
    if (w->params.interpolation == SDF_VOLUME_HERMITE && in.order == 0)
        return fail(req, SDF_EINVAL, "%s", "interpolation 'hermite' needs a first-order volume; "
                    "this one is zero order");
    float *grad = m == SDFD_SLICE_GRADIENT ? malloc(3 * n * sizeof *grad) : NULL;
    if (m == SDFD_SLICE_GRADIENT && !grad)
        return fail(req, SDF_ENOMEM, "out of memory for %s", "the slice's gradients");
    size_t bad = 0;
    int rc = sdf_volume_eval(s->volume, points, n, w->params.interpolation, values, grad, &bad);
    sdfd_metrics_points(req->srv->metrics, n);
    for (size_t i = 0; !rc && i < n; i++)
        values[i] = m == SDFD_SLICE_GRADIENT ? sqrtf(grad[3 * i] * grad[3 * i] +
                                                     grad[3 * i + 1] * grad[3 * i + 1] +
                                                     grad[3 * i + 2] * grad[3 * i + 2])
                    : m == SDFD_SLICE_DISTANCE ? fabsf(values[i])
                                               : values[i];
    free(grad);
    if (rc)
        return fail(req, rc, "%s", rc == SDF_ENONFINITE ? "a pixel's point is out of range"
                                                        : sdfd_strerror(rc));
    if (m != SDFD_SLICE_ERROR)
        return 0;
    if (!s->mesh[0])
        return fail(req, SDF_EINVAL, "%s", "mode error needs the volume's mesh, and this "
                    "volume was uploaded, not baked here");
    float *exact = malloc(n * sizeof *exact);
    if (!exact)
        return fail(req, SDF_ENOMEM, "out of memory for %s", "the exact distances");
    sdfd_slice_params exact_params = w->params;
    exact_params.sign = SDF_SIGN_AUTO;
    rc = query_mesh(req, s->mesh, SDF_MODE_SIGNED, &exact_params, points, n, 0, exact);
    if (rc == SDF_ENOTFOUND)
        fail(req, rc, "mode error needs the mesh '%.100s' the volume was baked from, which is no "
             "longer loaded", s->mesh);
    for (size_t i = 0; !rc && i < n; i++)
        values[i] = fabsf(values[i] - exact[i]);
    free(exact);
    return rc;
}

/* The values as the answer's body: a float32 (H, W) npy file, or the rendered PNG. */
static int encode(request *req, slice_work *w, float *values)
{
    const sdfd_slice_plane *p = &w->plane;
    if (w->params.npy) {
        size_t shape[2] = {p->height, p->width}, bytes = 4 * p->width * p->height;
        char header[128];
        long hl = sdf_npy_write_header(header, sizeof header, 2, shape);
        req->out_body = hl > 0 ? malloc((size_t)hl + bytes) : NULL;
        if (!req->out_body)
            return fail(req, SDF_ENOMEM, "out of memory for %s", "the npy file");
        memcpy(req->out_body, header, (size_t)hl);
        memcpy(req->out_body + hl, values, bytes);
        req->out_len = (size_t)hl + bytes;
        return 0;
    }
    unsigned char *rgb;
    size_t image_height;
    if (sdfd_slice_render(values, p->width, p->height, &w->scale, &rgb, &image_height))
        return fail(req, SDF_ENOMEM, "out of memory for %s", "the picture");
    int rc = sdfd_png_encode(rgb, p->width, image_height, &req->out_body, &req->out_len,
                             req->diag.message, sizeof req->diag.message);
    free(rgb);
    return req->work_rc = rc;
}

/* The box the default bounds come from: the mesh's, or the volume's nodes'. */
static int subject_box(request *req, sdfd_stored_volume *s, double lo[3], double hi[3])
{
    if (s) {
        sdf_volume_info in;
        sdf_volume_get_info(s->volume, &in);
        for (int a = 0; a < 3; a++)
            lo[a] = in.origin[a], hi[a] = in.origin[a] + (double)(in.dims[a] - 1) * in.spacing[a];
        return 0;
    }
    sdf_mesh *mesh = sdfd_registry_get(req->srv->registry, req->name, strlen(req->name));
    if (!mesh)
        return fail(req, SDF_ENOTFOUND, "no mesh named '%s'", req->name);
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    sdf_mesh_release(mesh);
    for (int a = 0; a < 3; a++)
        lo[a] = r.bbox_min[a], hi[a] = r.bbox_max[a];
    return 0;
}

static void run_slice(request *req)
{
    slice_work *w = req->route_state;
    sdfd_server *srv = req->srv;
    sdfd_stored_volume *s = NULL;
    if (w->params.volume && !(s = sdfd_volumes_get(srv->volumes, req->name))) {
        fail(req, SDF_ENOTFOUND, "no volume named '%s'", req->name);
        return;
    }
    double lo[3], hi[3];
    if (subject_box(req, s, lo, hi))
        return;
    sdfd_slice_layout(&w->params, lo, hi, s ? 0 : 0.1, &w->plane);
    size_t n = w->plane.width * w->plane.height;
    /* points, values, and at most the answers' words or the picture besides */
    size_t bytes = n * (12 + 4 + 16);
    if (n > srv->cfg.max_points) {
        w->argument = "size";
        snprintf(req->diag.message, sizeof req->diag.message,
                 "the slice has %zu pixels, over --max-points %zu", n, srv->cfg.max_points);
        req->work_rc = SDF_ELIMIT;
    } else if (sdfd_buffer_reserve(srv, bytes)) {
        snprintf(req->diag.message, sizeof req->diag.message, SDFD_BUFFER_BUSY_FMT,
                 srv->cfg.max_buffered_bytes);
        req->work_rc = SDFD_EBUSY;
    } else {
        req->reserved += bytes; /* released when the request completes */
        float *points = malloc(3 * n * sizeof *points), *values = malloc(n * sizeof *values);
        if (!points || !values)
            fail(req, SDF_ENOMEM, "out of memory for %s", "the slice");
        else
            sdfd_slice_points(&w->plane, points);
        if (!req->work_rc && !(s ? slice_volume(req, w, s, points, n, values)
                                 : slice_mesh(req, w, points, n, values))) {
            int diverging = w->params.mode == SDFD_SLICE_SIGNED ||
                            w->params.mode == SDFD_SLICE_FILTERED;
            sdfd_slice_scale_of(values, n, diverging, w->params.step, &w->scale);
            encode(req, w, values);
        }
        free(points);
        free(values);
    }
    sdfd_volume_release(s);
}

/* ---- the arguments (req->args, which admission collected and checked) ---------------------- */

enum MHD_Result sdfd_http_slice(request *req)
{
    slice_work *w = calloc(1, sizeof *w);
    if (!w)
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory");
    req->route_state = w; /* freed when the request completes */
    w->argument = "";
    char err[300];
    int rc = sdfd_slice_parse(&req->args, req->op->id == SDFD_OP_VOLUME_SLICE, &w->params, err,
                              sizeof err, &w->argument);
    if (rc)
        return sdfd_http_refuse(req, rc, w->argument, "%s", err);
    return sdfd_http_start_thread(req, run_slice, reply_slice);
}
