/* query.c - sdf_query: the entry point that picks how a batch is answered.
 *
 * A batch is checked whole first (points/points.h: finite coordinates, valid arguments) so
 * that a bad point fails the call before any output is written. A large batch laid out as a
 * lattice on a closed mesh is then answered by closest-feature scan conversion (scan/scan.h),
 * whose winners get the same exact test and the same finish as the point engine
 * (sdf__query_finish), so the same floats; any other batch goes to the point engine
 * (points/points.h), point by point. This file sits above both, which is why the choice is
 * made here and nowhere below. */
#include "query/query.h"

#include <math.h>
#include <stdlib.h>

#include "core/workspace.h"
#include "geom/triangle.h"
#include "mesh/mesh.h"
#include "points/points.h"
#include "scan/scan.h"

/* A batch laid out as a lattice is answered by the scan (the same floats) when it has at
 * least LATTICE_MIN_POINTS points and half as many as the mesh has faces, edges and vertices:
 * below that the scan's set-up (adjacency, a coarse lattice of queries, per-feature work)
 * outweighs the packet traversals it saves. On a finer mesh the packets slow down as much as
 * the set-up grows (a far point rejects more, smaller triangles), so past LATTICE_PAYS_POINTS
 * points the scan pays whatever the mesh (docs/performance.md has the runs behind both
 * thresholds). Its scratch, ~130 bytes a feature, is kept within LATTICE_FEATURES_PER_POINT
 * features a point of the batch. */
#define LATTICE_MIN_POINTS 32768
#define LATTICE_PAYS_POINTS 131072
#define LATTICE_FEATURES_PER_POINT 32

static const float *lattice_point(const float *points, size_t stride, size_t i)
{
    return (const float *)((const char *)points + i * stride);
}

int sdf__find_lattice(const float *points, size_t stride, size_t count, size_t dims[3],
                      float *axis[3])
{
    stride = stride ? stride : 3 * sizeof(float);
    axis[0] = axis[1] = axis[2] = NULL;
    if (count < 8)
        return 0;
    const float *p0 = lattice_point(points, stride, 0);
    size_t nx = 1, ny = 1;
    while (nx < count && lattice_point(points, stride, nx)[1] == p0[1] &&
           lattice_point(points, stride, nx)[2] == p0[2])
        nx++;
    while (ny * nx < count && lattice_point(points, stride, ny * nx)[2] == p0[2])
        ny++;
    if (nx < 2 || ny < 2 || count % (nx * ny) || count / (nx * ny) < 2)
        return 0;
    dims[0] = nx, dims[1] = ny, dims[2] = count / (nx * ny);
    size_t step[3] = {1, nx, nx * ny};
    for (int a = 0; a < 3; a++) {
        axis[a] = malloc(dims[a] * sizeof(float));
        for (size_t i = 0; axis[a] && i < dims[a]; i++)
            axis[a][i] = lattice_point(points, stride, i * step[a])[a];
    }
    int ok = axis[0] && axis[1] && axis[2];
    /* Every point on its node, axis by axis (nested loops: no division per point). */
    for (size_t k = 0, n = 0; ok && k < dims[2]; k++)
        for (size_t j = 0; ok && j < ny; j++)
            for (size_t i = 0; ok && i < nx; i++, n++) {
                const float *p = lattice_point(points, stride, n);
                ok = p[0] == axis[0][i] && p[1] == axis[1][j] && p[2] == axis[2][k];
            }
    if (!ok) {
        for (int a = 0; a < 3; a++)
            free(axis[a]), axis[a] = NULL;
    }
    return ok;
}

/* Is a checked batch of `count` points large enough, on this mesh and with these options,
 * for the scan to pay (LATTICE_*)? */
static int lattice_pays(const sdf_mesh *m, size_t count, const sdf_query_options *opts,
                        sdf_sign_method sign)
{
    size_t features = m->report.triangles + m->edge_count + m->report.vertices;
    size_t enough = features / 2;
    if (enough > LATTICE_PAYS_POINTS)
        enough = features / LATTICE_FEATURES_PER_POINT > LATTICE_PAYS_POINTS
                     ? features / LATTICE_FEATURES_PER_POINT
                     : LATTICE_PAYS_POINTS;
    return count >= LATTICE_MIN_POINTS && count >= enough &&
           !(opts && opts->traversal == SDF_TRAVERSAL_SINGLE) && sdf__scan_supported(m, sign);
}

/* A checked batch through the scan. 0 when answered; otherwise (not an evenly spaced lattice,
 * a mesh or sign the scan does not take, no memory) the point engine answers it, with the
 * same floats. */
static int lattice_query(const sdf_mesh *m, const float *points, size_t count,
                         const sdf_query_options *opts, sdf_query_result *out)
{
    sdf_sign_method sign = opts ? opts->sign : SDF_SIGN_AUTO;
    if (sign == SDF_SIGN_AUTO)
        sign = m->report.auto_sign;
    if (!lattice_pays(m, count, opts, sign))
        return -1;
    size_t dims[3];
    float *axis[3] = {NULL, NULL, NULL};
    if (!sdf__find_lattice(points, opts ? opts->point_stride : 0, count, dims, axis))
        return -1;
    int threads = opts ? opts->threads : 0;
    sdf_query_options o = {.sign = sign, .threads = threads,
                           .workspace = opts ? opts->workspace : NULL};
    sdf__scan *scan = NULL;
    int rc = !sdf__scan_fits(dims[0], dims[1], 0, threads)
                 ? -1
                 : sdf__scan_create_lattice(m, dims, (const float *const *)axis, &o, &scan);
    size_t slice = dims[0] * dims[1], per_call = rc ? 1 : sdf__scan_slices_per_call(scan);
    for (size_t k = 0; !rc && k < dims[2]; k += per_call) {
        sdf_query_result part = sdf__result_at(out, k * slice);
        rc = sdf__scan_slices(scan, k, k + per_call < dims[2] ? k + per_call : dims[2], &part);
    }
    sdf__scan_destroy(scan);
    free(axis[0]), free(axis[1]), free(axis[2]);
    return rc;
}

int sdf__query(const sdf_mesh *mesh, const float *points, size_t count,
               const sdf_query_options *opts, sdf_query_result *out)
{
    int rc = sdf__query_check(mesh, points, count, opts, out);
    if (rc || lattice_query(mesh, points, count, opts, out) == 0)
        return rc;
    return sdf__query_checked_points(mesh, points, count, opts, out);
}

/* The unit normals of the triangles `ids` (n of them) into normal[3n]. */
static void triangle_normals(const sdf_mesh *m, const uint32_t *ids, size_t n, float *normal)
{
    for (size_t i = 0; i < n; i++) {
        const uint32_t *t = m->triangles + 3 * (size_t)ids[i];
        double v[3][3], w[3];
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++)
                v[c][k] = m->positions[3 * t[c] + k];
        sdf__triangle_normal(v[0], v[1], v[2], w);
        double len = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        for (int k = 0; k < 3; k++)
            normal[3 * i + k] = len > 0 ? (float)(w[k] / len) : 0.0f;
    }
}

int sdf_query(const sdf_mesh *mesh, const float *points, size_t count,
              const sdf_query_options *opts, sdf_query_result *out)
{
    /* Normals come from the closest triangles' ids, asked for here if the caller did not. */
    sdf_query_result o = out ? *out : (sdf_query_result){0};
    uint32_t *ids = NULL;
    if (out && out->normal && !out->triangle && count &&
        !(o.triangle = ids = malloc(count * sizeof *ids)))
        return SDF_ENOMEM;
    sdf__ws_call call;
    int rc = sdf__query(mesh, points, count, sdf__ws_enter(opts, &call), out ? &o : NULL);
    sdf__ws_leave(&call);
    if (!rc && out && out->normal)
        triangle_normals(mesh, o.triangle, count, out->normal);
    if (out)
        out->bad_index = o.bad_index;
    free(ids);
    return rc;
}
