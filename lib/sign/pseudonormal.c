/* pseudonormal.c - angle-weighted pseudonormals (see pseudonormal.h). */
#include "sign/pseudonormal.h"

#include <math.h>
#include <stdlib.h>

#include "core/parallel.h"
#include "geom/triangle.h"
#include "sdf/sdf.h"

static void load(const float *positions, uint32_t v, double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = positions[3 * v + i];
}

static double normalize(double v[3])
{
    double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (len > 0)
        for (int i = 0; i < 3; i++)
            v[i] /= len;
    return len;
}

/* The unit normal of a triangle in double (zero for zero area), from its corners `p`, for
 * the edge and vertex sums. */
static double face_normal(const double p[3][3], double n[3])
{
    double u[3], v[3];
    for (int i = 0; i < 3; i++) {
        u[i] = p[1][i] - p[0][i];
        v[i] = p[2][i] - p[0][i];
    }
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
    return normalize(n);
}

static void load_corners(const float *positions, const uint32_t *tri, double p[3][3])
{
    for (int k = 0; k < 3; k++)
        load(positions, tri[k], p[k]);
}

static void store_unit(float *dst, double v[3])
{
    normalize(v);
    for (int i = 0; i < 3; i++)
        dst[i] = (float)v[i];
}

/* One triangle's unit normal and interior angles. */
typedef struct face_terms {
    double normal[3], angle[3];
    int has_normal; /* 0: zero area, contributes nothing */
} face_terms;

typedef struct terms_job {
    const float *positions;
    const uint32_t *triangles;
    face_terms *terms;
} terms_job;

/* The interior angle at corner k is atan2(|u x v|, u . v) for the corner's two edge vectors
 * u, v: stable for all angles, needing no unit vectors, and |u x v| is the same at all three
 * corners (twice the area). */
static void compute_terms(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const terms_job *job = ctx;
    for (size_t t = begin; t < end; t++) {
        face_terms *f = &job->terms[t];
        double p[3][3];
        load_corners(job->positions, job->triangles + 3 * t, p);
        double twice_area = face_normal(p, f->normal);
        f->has_normal = twice_area > 0;
        for (int k = 0; k < 3 && f->has_normal; k++) {
            const double *a = p[k], *b = p[(k + 1) % 3], *c = p[(k + 2) % 3];
            double dot = (b[0] - a[0]) * (c[0] - a[0]) + (b[1] - a[1]) * (c[1] - a[1]) +
                         (b[2] - a[2]) * (c[2] - a[2]);
            f->angle[k] = atan2(twice_area, dot);
        }
    }
}

typedef struct edges_job {
    const face_terms *terms;
    const size_t *edge_start;
    const uint32_t *edge_face;
    float *out;
} edges_job;

/* Each edge's normal: the sum of its faces' normals (weight pi, common to all: dropped) in
 * triangle order, made unit. */
static void edges_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const edges_job *job = ctx;
    for (size_t e = begin; e < end; e++) {
        double sum[3] = {0, 0, 0};
        for (size_t s = job->edge_start[e]; s < job->edge_start[e + 1]; s++) {
            const face_terms *f = &job->terms[job->edge_face[s]];
            if (!f->has_normal)
                continue;
            for (int i = 0; i < 3; i++)
                sum[i] += f->normal[i];
        }
        store_unit(job->out + 3 * e, sum);
    }
}

typedef struct units_job {
    double *sum;
    float *out;
} units_job;

static void units_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const units_job *job = ctx;
    for (size_t v = begin; v < end; v++)
        store_unit(job->out + 3 * v, job->sum + 3 * v);
}

int sdf__pseudonormals_create(const float *positions, size_t vertex_count,
                              const uint32_t *triangles, size_t triangle_count,
                              const size_t *edge_start, const uint32_t *edge_face,
                              size_t edge_count,
                              sdf__pseudonormals **out)
{
    sdf__pseudonormals *pn = calloc(1, sizeof *pn);
    double *vertex_sum = calloc(3 * vertex_count + 1, sizeof *vertex_sum);
    face_terms *terms = malloc((triangle_count + 1) * sizeof *terms);
    if (pn) {
        pn->edge = malloc((3 * edge_count + 1) * sizeof(float));
        pn->vertex = malloc((3 * vertex_count + 1) * sizeof(float));
    }
    if (!pn || !vertex_sum || !terms || !pn->edge || !pn->vertex) {
        free(vertex_sum);
        free(terms);
        sdf__pseudonormals_destroy(pn);
        return SDF_ENOMEM;
    }
    /* The normals and corner angles (the costly part: square roots and atan2) and the edges'
     * sums (each over its own faces) on all CPUs; the vertices' sums in triangle order on one,
     * so the result does not depend on threads. */
    terms_job job = {positions, triangles, terms};
    sdf__parallel_for(triangle_count, 4096, 0, compute_terms, &job);
    edges_job edges = {terms, edge_start, edge_face, pn->edge};
    sdf__parallel_for(edge_count, 4096, 0, edges_range, &edges);
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *tri = triangles + 3 * t;
        const face_terms *f = &terms[t];
        if (!f->has_normal)
            continue;
        for (int k = 0; k < 3; k++)
            for (int i = 0; i < 3; i++)
                vertex_sum[3 * tri[k] + i] += f->angle[k] * f->normal[i];
    }
    free(terms);
    units_job units = {vertex_sum, pn->vertex};
    sdf__parallel_for(vertex_count, 4096, 0, units_range, &units);
    free(vertex_sum);
    pn->bytes = (3 * edge_count + 3 * vertex_count) * sizeof(float);
    *out = pn;
    return 0;
}

void sdf__pseudonormals_destroy(sdf__pseudonormals *pn)
{
    if (!pn)
        return;
    free(pn->edge);
    free(pn->vertex);
    free(pn);
}

static int copy_if_nonzero(const float *src, float n[3])
{
    if (src[0] == 0 && src[1] == 0 && src[2] == 0)
        return 0;
    n[0] = src[0], n[1] = src[1], n[2] = src[2];
    return 1;
}

void sdf__pseudonormal(const sdf__pseudonormals *pn, const uint32_t *triangles,
                       const uint32_t *edge_of, uint32_t tri, int feature, const double face[3],
                       float n[3])
{
    const uint32_t *t = triangles + 3 * (size_t)tri;
    if (feature >= SDF__VERT0 && copy_if_nonzero(pn->vertex + 3 * (size_t)t[feature - SDF__VERT0], n))
        return;
    if (feature >= SDF__EDGE0 && feature <= SDF__EDGE2) {
        uint32_t e = edge_of[3 * (size_t)tri + (feature - SDF__EDGE0)];
        if (e != SDF__NO_EDGE && copy_if_nonzero(pn->edge + 3 * (size_t)e, n))
            return;
    }
    double len = sqrt(face[0] * face[0] + face[1] * face[1] + face[2] * face[2]);
    if (len > 0 && isfinite(len)) {
        double inv = 1 / len;
        n[0] = (float)(face[0] * inv), n[1] = (float)(face[1] * inv), n[2] = (float)(face[2] * inv);
        return;
    }
    for (int k = 0; k < 3; k++)
        if (copy_if_nonzero(pn->vertex + 3 * (size_t)t[k], n))
            return;
    n[0] = n[1] = n[2] = 0;
}
