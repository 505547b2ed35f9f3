/* opslice.c - slice images of meshes and volumes (opslice.h).
 *
 * The arguments are checked at once; everything after runs on a worker thread, like an
 * upload: the mesh or volume is looked up through the cache (so a stored item not yet in
 * memory is loaded, as a query of it would be), the slice's pixel centres are one query
 * handed to the batcher through the same admission as any HTTP or binary query (queries.h),
 * and the worker waits for its answer, then colours and encodes it. The memory a slice holds
 * while it is computed (points, answers, picture) is counted against --max-buffered-bytes,
 * as request bodies are. */
#include "ops/opslice.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "ops/pngenc.h"
#include "ops/queries.h"
#include "ops/slice.h"
#include "ops/slicerender.h"

typedef struct slice_work {
    sdfd_slice_params params;
    sdfd_slice_plane plane;
    sdfd_slice_scale scale;
} slice_work;

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

static int fail(sdfd_call *call, int rc, const char *fmt, const char *detail)
{
    sdfd_call_fail(call, rc, fmt, detail);
    return rc;
}

/* The mesh `name` at `count` points through the batcher, as one query: values[i] is the
 * distance, or with `magnitude` the gradient's length. */
static int query_mesh(sdfd_call *call, const char *name, sdf_proto_mode mode,
                      const sdfd_slice_params *p, const float *points, size_t count,
                      int magnitude, float *values)
{
    unsigned per = sdf_proto_words(mode);
    uint32_t *words = malloc(count * per * sizeof *words);
    if (!words)
        return fail(call, SDF_ENOMEM, "out of memory for %s", "the slice's answers");
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
    int rc = sdfd_query_admit(call->srv, &q, err, sizeof err);
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
    return rc ? fail(call, rc, "%.250s", err) : 0;
}

static int slice_mesh(sdfd_call *call, slice_work *w, const float *points, size_t n, float *values)
{
    static const sdf_proto_mode modes[] = {SDF_MODE_SIGNED, SDF_MODE_DISTANCE,
                                           SDF_MODE_FILTERED, SDF_MODE_GRADIENT};
    sdfd_slice_mode m = w->params.mode;
    return query_mesh(call, call->name, modes[m], &w->params, points, n,
                      m == SDFD_SLICE_GRADIENT, values);
}

static int slice_volume(sdfd_call *call, slice_work *w, const sdfd_stored_volume *s,
                        const float *points, size_t n, float *values)
{
    sdfd_slice_mode m = w->params.mode;
    sdf_volume_info in;
    sdf_volume_get_info(s->volume, &in);
    if (w->params.interpolation == SDF_VOLUME_HERMITE && in.order == 0)
        return fail(call, SDF_EINVAL, "%s", "interpolation 'hermite' needs a first-order volume; "
                    "this one is zero order");
    float *grad = m == SDFD_SLICE_GRADIENT ? malloc(3 * n * sizeof *grad) : NULL;
    if (m == SDFD_SLICE_GRADIENT && !grad)
        return fail(call, SDF_ENOMEM, "out of memory for %s", "the slice's gradients");
    size_t bad = 0;
    int rc = sdf_volume_eval(s->volume, points, n, w->params.interpolation, values, grad, &bad);
    sdfd_metrics_points(call->srv->metrics, n);
    for (size_t i = 0; !rc && i < n; i++)
        values[i] = m == SDFD_SLICE_GRADIENT ? sqrtf(grad[3 * i] * grad[3 * i] +
                                                     grad[3 * i + 1] * grad[3 * i + 1] +
                                                     grad[3 * i + 2] * grad[3 * i + 2])
                    : m == SDFD_SLICE_DISTANCE ? fabsf(values[i])
                                               : values[i];
    free(grad);
    if (rc)
        return fail(call, rc, "%s", rc == SDF_ENONFINITE ? "a pixel's point is out of range"
                                                        : sdfd_strerror(rc));
    if (m != SDFD_SLICE_ERROR)
        return 0;
    if (!s->mesh[0])
        return fail(call, SDF_EINVAL, "%s", "mode error needs the volume's mesh, and this "
                    "volume was uploaded, not baked here");
    float *exact = malloc(n * sizeof *exact);
    if (!exact)
        return fail(call, SDF_ENOMEM, "out of memory for %s", "the exact distances");
    sdfd_slice_params exact_params = w->params;
    exact_params.sign = SDF_SIGN_AUTO;
    rc = query_mesh(call, s->mesh, SDF_MODE_SIGNED, &exact_params, points, n, 0, exact);
    if (rc == SDF_ENOTFOUND)
        fail(call, rc, "mode error needs the mesh '%.100s' the volume was baked from, which is no "
             "longer loaded", s->mesh);
    for (size_t i = 0; !rc && i < n; i++)
        values[i] = fabsf(values[i] - exact[i]);
    free(exact);
    return rc;
}

/* The values as the answer's body: a float32 (H, W) npy file, or the rendered PNG. */
static int encode(sdfd_call *call, slice_work *w, float *values)
{
    const sdfd_slice_plane *p = &w->plane;
    sdfd_result *r = &call->result;
    if (w->params.npy) {
        size_t shape[2] = {p->height, p->width}, bytes = 4 * p->width * p->height;
        char header[128];
        long hl = sdf_npy_write_header(header, sizeof header, 2, shape);
        r->bytes = hl > 0 ? malloc((size_t)hl + bytes) : NULL;
        if (!r->bytes)
            return fail(call, SDF_ENOMEM, "out of memory for %s", "the npy file");
        memcpy(r->bytes, header, (size_t)hl);
        memcpy(r->bytes + hl, values, bytes);
        r->len = (size_t)hl + bytes;
        return 0;
    }
    unsigned char *rgb;
    size_t image_height;
    char msg[300];
    if (sdfd_slice_render(values, p->width, p->height, &w->scale, &rgb, &image_height))
        return fail(call, SDF_ENOMEM, "out of memory for %s", "the picture");
    int rc = sdfd_png_encode(rgb, p->width, image_height, &r->bytes, &r->len, msg, sizeof msg);
    free(rgb);
    return rc ? fail(call, rc, "%s", msg) : 0;
}

static void vector_field(sdfd_call *call, const char *name, const double *v)
{
    sdfd_call_field(call, name, "%.9g,%.9g,%.9g", v[0], v[1], v[2]);
}

/* The answer's fields: the picture's size, the values' range and step, and where its
 * pixels lie in space. */
static void answer(sdfd_call *call, const slice_work *w)
{
    const sdfd_slice_plane *p = &w->plane;
    const sdfd_slice_scale *s = &w->scale;
    sdfd_call_field(call, "X-SDF-Slice-Size", "%zu,%zu", p->width, p->height);
    sdfd_call_field(call, "X-SDF-Slice-Range", "%.9g,%.9g", s->min, s->max);
    sdfd_call_field(call, "X-SDF-Slice-Step", "%.9g", s->step);
    vector_field(call, "X-SDF-Slice-First", p->first);
    vector_field(call, "X-SDF-Slice-Right", p->right);
    vector_field(call, "X-SDF-Slice-Down", p->down);
    call->result.status = 200;
    call->result.type = w->params.npy ? "application/x-npy" : "image/png";
    call->points = p->width * p->height;
}

/* The box the default bounds come from: the mesh's, or the volume's nodes'. */
static int subject_box(sdfd_call *call, sdfd_stored_volume *s, double lo[3], double hi[3])
{
    if (s) {
        sdf_volume_info in;
        sdf_volume_get_info(s->volume, &in);
        for (int a = 0; a < 3; a++)
            lo[a] = in.origin[a], hi[a] = in.origin[a] + (double)(in.dims[a] - 1) * in.spacing[a];
        return 0;
    }
    sdf_mesh *mesh = sdfd_call_lookup(call, SDFD_ITEM_MESH, call->name);
    if (!mesh)
        return call->result.code;
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    sdf_mesh_release(mesh);
    for (int a = 0; a < 3; a++)
        lo[a] = r.bbox_min[a], hi[a] = r.bbox_max[a];
    return 0;
}

/* The points, values and answers of n pixels: refused past --max-points or the buffer
 * budget, else reserved until the call is released. */
static int reserve(sdfd_call *call, size_t n)
{
    sdfd_server *srv = call->srv;
    size_t bytes = n * (12 + 4 + 16); /* points, values, at most the words or the picture */
    if (n > srv->cfg.max_points) {
        sdfd_call_fail(call, SDF_ELIMIT, "the slice has %zu pixels, over --max-points %zu", n,
                       srv->cfg.max_points);
        call->result.argument = "size";
        return -1;
    }
    if (sdfd_buffer_reserve(srv, bytes)) {
        sdfd_call_fail(call, SDFD_EBUSY, SDFD_BUFFER_BUSY_FMT, srv->cfg.max_buffered_bytes);
        return -1;
    }
    call->reserved += bytes;
    return 0;
}

static void run_slice(sdfd_call *call)
{
    slice_work *w = call->state;
    sdfd_stored_volume *s = NULL;
    double lo[3], hi[3];
    if (w->params.volume && !(s = sdfd_call_lookup(call, SDFD_ITEM_VOLUME, call->name)))
        return;
    if (subject_box(call, s, lo, hi)) {
        sdfd_volume_release(s);
        return;
    }
    sdfd_slice_layout(&w->params, lo, hi, s ? 0 : 0.1, &w->plane);
    size_t n = w->plane.width * w->plane.height;
    float *points = NULL, *values = NULL;
    if (!reserve(call, n)) {
        points = malloc(3 * n * sizeof *points), values = malloc(n * sizeof *values);
        if (!points || !values)
            fail(call, SDF_ENOMEM, "out of memory for %s", "the slice");
        else
            sdfd_slice_points(&w->plane, points);
    }
    if (!call->result.code && !(s ? slice_volume(call, w, s, points, n, values)
                                  : slice_mesh(call, w, points, n, values))) {
        int diverging = w->params.mode == SDFD_SLICE_SIGNED ||
                        w->params.mode == SDFD_SLICE_FILTERED;
        sdfd_slice_scale_of(values, n, diverging, w->params.step, &w->scale);
        if (!encode(call, w, values))
            answer(call, w);
    }
    free(points);
    free(values);
    sdfd_volume_release(s);
}

int sdfd_op_slice(sdfd_call *call)
{
    slice_work *w = calloc(1, sizeof *w);
    if (!w)
        return sdfd_call_fail(call, SDF_ENOMEM, "out of memory");
    call->state = w; /* freed with the call */
    char err[300];
    const char *argument = "";
    int rc = sdfd_slice_parse(call->args, call->op->id == SDFD_OP_VOLUME_SLICE, &w->params, err,
                              sizeof err, &argument);
    if (rc) {
        sdfd_call_fail(call, rc, "%s", err);
        call->result.argument = argument;
        return SDFD_CALL_READY;
    }
    return sdfd_call_defer(call, run_slice);
}
