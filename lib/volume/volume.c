/* volume.c - the sdf_volume handle and its evaluation: nearest and trilinear reconstruction
 * of zero-order grids and first-order Taylor distance fields (TDF paper, sec. 3-4), and the
 * tricubic Hermite reconstruction of first-order ones (volume/hermite.h), with the exact
 * gradient of what is reconstructed. */
#include "volume/volume.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/bigmem.h"
#include "core/diag.h"
#include "core/parallel.h"
#include "volume/hermite.h"
#include "volume/pack.h"

#define EVAL_CHUNK 16384 /* points per work item: a few milliseconds */

int sdf_volume_channels(const sdf_volume_info *info)
{
    return info->order == 1 && info->encoding == SDF_ENCODING_FLOAT32 ? 4 : 1;
}

int sdf__volume_check_info(const sdf_volume_info *info, sdf_diag *diag)
{
    size_t nodes = 1;
    for (int a = 0; a < 3; a++) {
        if (info->dims[a] < 2 || info->dims[a] > SDF_VOLUME_MAX_DIM)
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "volume dimension %c is %zu; it must be 2..%d", "xyz"[a],
                                 info->dims[a], SDF_VOLUME_MAX_DIM);
        if (!isfinite(info->origin[a]) || !isfinite(info->spacing[a]) || !(info->spacing[a] > 0))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "volume origin and spacing must be finite, spacing > 0");
        /* Past these, a node's coordinate or a gradient's 1 / spacing is infinite. */
        double far = info->origin[a] + info->spacing[a] * (double)(info->dims[a] - 1);
        if (!isfinite(far) || !isfinite(1 / info->spacing[a]))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "volume along %c (origin %g, spacing %g, %zu nodes) reaches "
                                 "beyond the doubles", "xyz"[a], info->origin[a],
                                 info->spacing[a], info->dims[a]);
        nodes *= info->dims[a];
    }
    if (nodes > SDF_VOLUME_MAX_NODES)
        return sdf__diag_set(diag, SDF_ELIMIT, 0, -1, "volume of %zu nodes; at most %zu", nodes,
                             SDF_VOLUME_MAX_NODES);
    if (info->order != 0 && info->order != 1)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "volume order must be 0 or 1, not %d",
                             info->order);
    if ((unsigned)info->normalize > SDF_NORMALIZE_GRADIENT)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown normalisation");
    if ((unsigned)info->encoding > SDF_ENCODING_PACKED32)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown volume encoding");
    if (info->encoding == SDF_ENCODING_PACKED32 && info->order != 1)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                             "the packed32 encoding is for first-order volumes");
    if (info->encoding == SDF_ENCODING_PACKED32 &&
        !(isfinite(info->packed_range) && info->packed_range > 0 && isfinite(info->packed_center)))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                             "packed range must be finite and > 0, its centre finite");
    return 0;
}

int sdf__volume_alloc(const sdf_volume_info *info, sdf_volume **out)
{
    *out = NULL;
    sdf_volume *v = calloc(1, sizeof *v);
    if (!v)
        return SDF_ENOMEM;
    v->info = *info;
    v->nodes = info->dims[0] * info->dims[1] * info->dims[2];
    v->channels = sdf_volume_channels(info);
    v->data.p = sdf__big_alloc(v->nodes * (size_t)v->channels * 4);
    if (!v->data.p) {
        free(v);
        return SDF_ENOMEM;
    }
    *out = v;
    return 0;
}

int sdf_volume_create(const sdf_volume_info *info, const void *data, sdf_volume **out,
                      sdf_diag *diag)
{
    if (!out)
        return SDF_EINVAL;
    *out = NULL;
    if (!info || !data)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "no volume description or data");
    int rc = sdf__volume_check_info(info, diag);
    if (rc)
        return rc;
    sdf_volume *v;
    if ((rc = sdf__volume_alloc(info, &v)))
        return sdf__diag_set(diag, rc, 0, -1, "no memory for the volume");
    size_t words = v->nodes * (size_t)v->channels;
    memcpy(v->data.p, data, words * 4);
    if (info->encoding == SDF_ENCODING_FLOAT32)
        for (size_t i = 0; i < words; i++)
            if (!isfinite(v->data.f[i])) {
                sdf_volume_destroy(v);
                return sdf__diag_set(diag, SDF_ENONFINITE, 0, (long long)i * 4,
                                     "volume word %zu is not finite", i);
            }
    *out = v;
    return 0;
}

void sdf_volume_destroy(sdf_volume *volume)
{
    if (!volume)
        return;
    sdf__big_free(volume->data.p);
    free(volume);
}

void sdf_volume_get_info(const sdf_volume *volume, sdf_volume_info *out) { *out = volume->info; }

const void *sdf_volume_data(const sdf_volume *volume) { return volume->data.p; }

size_t sdf_volume_data_bytes(const sdf_volume *volume)
{
    return volume->nodes * (size_t)volume->channels * 4;
}

/* ---- evaluation ------------------------------------------------------------------------ */

void sdf__volume_node_plane(const sdf_volume *v, size_t i, size_t j, size_t k, double plane[4])
{
    const sdf_volume_info *in = &v->info;
    size_t idx = (k * in->dims[1] + j) * in->dims[0] + i;
    if (in->encoding == SDF_ENCODING_FLOAT32) {
        const float *c = v->data.f + 4 * idx;
        plane[0] = c[0], plane[1] = c[1], plane[2] = c[2], plane[3] = c[3];
        return;
    }
    double n[3], value, at[3];
    sdf__unpack_plane(v->data.u[idx], in->packed_range, n, &value);
    value += in->packed_center;
    sdf__volume_node(in, i, j, k, at);
    plane[0] = n[0], plane[1] = n[1], plane[2] = n[2];
    plane[3] = value - (n[0] * at[0] + n[1] * at[1] + n[2] * at[2]);
}

static double node_value(const sdf_volume *v, size_t i, size_t j, size_t k)
{
    const sdf_volume_info *in = &v->info;
    return v->data.f[(k * in->dims[1] + j) * in->dims[0] + i];
}

/* Where p falls along one axis: the cell's first node, the fraction t in it, and whether
 * the coordinate was clamped to the volume (then the field does not vary along the axis
 * through the lookup). */
typedef struct axis_pos {
    size_t cell;
    double t;
    int clamped;
} axis_pos;

static axis_pos locate(double p, double origin, double spacing, size_t dim)
{
    axis_pos a = {0, 0, 0};
    double u = (p - origin) / spacing, last = (double)(dim - 1);
    if (u <= 0) {
        a.clamped = u < 0;
        return a;
    }
    if (u >= last) {
        a.cell = dim - 2, a.t = 1, a.clamped = u > last;
        return a;
    }
    a.cell = (size_t)u;
    if (a.cell > dim - 2)
        a.cell = dim - 2;
    a.t = u - (double)a.cell;
    return a;
}

static size_t nearest_node(double p, double origin, double spacing, size_t dim)
{
    double u = (p - origin) / spacing;
    if (!(u > 0))
        return 0;
    if (u >= (double)(dim - 1))
        return dim - 1;
    return (size_t)floor(u + 0.5);
}

/* Central difference of the node values along `axis` at node n (one-sided at the ends). */
static double node_difference(const sdf_volume *v, const size_t n[3], int axis)
{
    size_t lo[3] = {n[0], n[1], n[2]}, hi[3] = {n[0], n[1], n[2]};
    if (lo[axis] > 0)
        lo[axis]--;
    if (hi[axis] + 1 < v->info.dims[axis])
        hi[axis]++;
    double h = (double)(hi[axis] - lo[axis]) * v->info.spacing[axis];
    return (node_value(v, hi[0], hi[1], hi[2]) - node_value(v, lo[0], lo[1], lo[2])) / h;
}

static void eval_nearest(const sdf_volume *v, const double p[3], double *value, double grad[3])
{
    const sdf_volume_info *in = &v->info;
    size_t n[3];
    for (int a = 0; a < 3; a++)
        n[a] = nearest_node(p[a], in->origin[a], in->spacing[a], in->dims[a]);
    if (in->order == 0) {
        *value = node_value(v, n[0], n[1], n[2]);
        for (int a = 0; a < 3; a++)
            grad[a] = node_difference(v, n, a);
        return;
    }
    double pl[4];
    sdf__volume_node_plane(v, n[0], n[1], n[2], pl);
    *value = pl[0] * p[0] + pl[1] * p[1] + pl[2] * p[2] + pl[3];
    grad[0] = pl[0], grad[1] = pl[1], grad[2] = pl[2];
}

/* Trilinear: value = sum_c w_c(p) F_c(p), F_c the corner's value (order 0) or its plane
 * evaluated at p (order 1: interpolating the coefficients and then evaluating is the same,
 * sec. 3). The gradient is sum_c w_c grad F_c + sum_c F_c grad w_c. */
static void eval_trilinear(const sdf_volume *v, const double p[3], double *value, double grad[3])
{
    const sdf_volume_info *in = &v->info;
    axis_pos ax[3];
    for (int a = 0; a < 3; a++)
        ax[a] = locate(p[a], in->origin[a], in->spacing[a], in->dims[a]);
    double sum = 0, g[3] = {0, 0, 0};
    for (int c = 0; c < 8; c++) {
        int bit[3] = {c & 1, (c >> 1) & 1, (c >> 2) & 1};
        double f[3], df[3]; /* the corner's weight factor per axis and its derivative */
        for (int a = 0; a < 3; a++) {
            f[a] = bit[a] ? ax[a].t : 1 - ax[a].t;
            df[a] = ax[a].clamped ? 0 : (bit[a] ? 1 : -1) / in->spacing[a];
        }
        double w = f[0] * f[1] * f[2];
        double dw[3] = {df[0] * f[1] * f[2], f[0] * df[1] * f[2], f[0] * f[1] * df[2]};
        size_t i = ax[0].cell + (size_t)bit[0], j = ax[1].cell + (size_t)bit[1],
               k = ax[2].cell + (size_t)bit[2];
        double F;
        if (in->order == 0) {
            F = node_value(v, i, j, k);
        } else {
            double pl[4];
            sdf__volume_node_plane(v, i, j, k, pl);
            F = pl[0] * p[0] + pl[1] * p[1] + pl[2] * p[2] + pl[3];
            for (int a = 0; a < 3; a++)
                g[a] += w * pl[a];
        }
        sum += w * F;
        for (int a = 0; a < 3; a++)
            g[a] += F * dw[a];
    }
    *value = sum;
    grad[0] = g[0], grad[1] = g[1], grad[2] = g[2];
}

/* Tricubic Hermite (order 1): the planes of the 4 x 4 x 4 nodes around the point's cell. */
static void eval_hermite(const sdf_volume *v, const double p[3], double *value, double grad[3])
{
    const sdf_volume_info *in = &v->info;
    sdf__hermite_axis ax[3];
    for (int a = 0; a < 3; a++)
        sdf__hermite_locate(p[a], in->origin[a], in->spacing[a], in->dims[a], &ax[a]);
    double planes[64][4];
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++)
                sdf__volume_node_plane(v, ax[0].node[x], ax[1].node[y], ax[2].node[z],
                           planes[(z * 4 + y) * 4 + x]);
    sdf__hermite_eval(ax, planes, in->normalize == SDF_NORMALIZE_PLANE, value, grad);
}

typedef struct eval_batch {
    const sdf_volume *volume;
    const float *points;
    sdf_volume_filter filter;
    float *value, *gradient;
} eval_batch;

static void eval_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const eval_batch *b = ctx;
    for (size_t i = begin; i < end; i++) {
        const float *q = b->points + 3 * i;
        double p[3] = {q[0], q[1], q[2]}, val, g[3];
        if (b->filter == SDF_VOLUME_NEAREST)
            eval_nearest(b->volume, p, &val, g);
        else if (b->filter == SDF_VOLUME_HERMITE)
            eval_hermite(b->volume, p, &val, g);
        else
            eval_trilinear(b->volume, p, &val, g);
        b->value[i] = (float)val;
        if (b->gradient)
            for (int a = 0; a < 3; a++)
                b->gradient[3 * i + a] = (float)g[a];
    }
}

int sdf_volume_eval(const sdf_volume *volume, const float *points, size_t count,
                    sdf_volume_filter filter, float *value, float *gradient, size_t *bad_index)
{
    if (!volume || (!points && count) || (!value && count) ||
        (unsigned)filter > SDF_VOLUME_HERMITE ||
        (filter == SDF_VOLUME_HERMITE && volume->info.order != 1))
        return SDF_EINVAL;
    if (filter == SDF_VOLUME_DEFAULT)
        filter = volume->info.order == 1 ? SDF_VOLUME_HERMITE : SDF_VOLUME_TRILINEAR;
    /* The queries' one rule (sdf_query's too): NaN fails the comparison. */
    for (size_t i = 0; i < 3 * count; i++)
        if (!(fabsf(points[i]) <= SDF_MAX_COORDINATE)) {
            if (bad_index)
                *bad_index = i / 3;
            return SDF_ENONFINITE;
        }
    /* Each point on its own: any split over threads gives the same floats. */
    eval_batch b = {volume, points, filter, value, gradient};
    sdf__parallel_for(count, EVAL_CHUNK, 0, eval_range, &b);
    return 0;
}
