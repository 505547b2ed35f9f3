/* dual.c - dual contouring of a volume (dual.h). Two passes over z-layers, each
 * writing into lists of its own layer that are joined in layer order:
 *  1. per cell layer: the loops of its cells with surface (the active cells, from the bits),
 *     a vertex per loop, and for each active cell its first vertex and which loop each of its
 *     crossing edges belongs to;
 *  2. per node layer: a quad per crossing edge whose four cells lie in the grid, from those
 *     cells' records (an active cell's record is found by its rank among the active cells:
 *     its row word's first rank plus a popcount). */
#include "contour/dual.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contour/cell.h"
#include "contour/surface.h"
#include "core/grow.h"
#include "core/parallel.h"
#include "volume/volume.h"

#define MAX_VERTICES ((uint64_t)1 << 31)
#define EXTRA_BIT 0x80000000u
#define TRUNCATE 0.1 /* eigenvalues below this fraction of the largest are dropped (QEF) */

typedef struct cell_layer {
    uint64_t *active;      /* its cells with surface: a row of words per row of cells */
    uint32_t *rank;        /* per row word: the rank of its first active cell */
    uint32_t *first;       /* per active cell: its first vertex, counted in this layer */
    uint16_t (*edges)[12]; /* per active cell and edge: polygons out | in << 4 | face << 8 */
    size_t cells, cells_cap, edges_cap;
    float *pos;            /* 3 per vertex */
    size_t vertices, pos_cap;
    uint32_t *tri;         /* pass 2, node layer k: 3 per triangle (global ids, or EXTRA_BIT
                              and the number of one of this layer's extra vertices) */
    size_t tris, tri_cap;
    float *extra;          /* pass 2: 3 per vertex added at a split crossing (below) */
    size_t extras, extra_cap;
} cell_layer;

typedef struct job {
    const sdf__signs *s;
    cell_layer *layers;    /* n[2] of them: cell layers in pass 1, node layers in pass 2 */
    uint64_t *first;       /* per cell layer: its first vertex (global) */
    float *vertices;       /* pass 2: all of them, joined */
    uint64_t *rows;        /* pass 2: a row of words per worker */
    int failed;
} job;

/* ---- the quadratic error function -------------------------------------------------------- */

/* Eigen-decomposition of the symmetric 3x3 a (destroyed): eigenvalues on its diagonal, the
 * eigenvectors as v's columns (cyclic Jacobi). */
static void jacobi3(double a[3][3], double v[3][3])
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            v[r][c] = r == c;
    for (int sweep = 0; sweep < 12; sweep++)
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++) {
                if (fabs(a[p][q]) < 1e-300)
                    continue;
                double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
                double t = (theta >= 0 ? 1 : -1) / (fabs(theta) + sqrt(theta * theta + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 3; k++) { /* a = J^T a J */
                    double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - s * akq, a[k][q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; k++) {
                    double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk, a[q][k] = s * apk + c * aqk;
                }
                for (int k = 0; k < 3; k++) {
                    double vkp = v[k][p], vkq = v[k][q];
                    v[k][p] = c * vkp - s * vkq, v[k][q] = s * vkp + c * vkq;
                }
            }
}

/* The point x least in sum (n_i . (x - p_i))^2 nearest the mean of the p_i, with the
 * directions the normals barely constrain left at the mean (eigenvalues truncated). */
static void qef_point(const double (*p)[3], const double (*n)[3], int m, double out[3])
{
    double mean[3] = {0, 0, 0}, a[3][3] = {{0}}, b[3] = {0, 0, 0}, v[3][3];
    for (int i = 0; i < m; i++)
        for (int r = 0; r < 3; r++)
            mean[r] += p[i][r] / m;
    for (int i = 0; i < m; i++) {
        double d = 0;
        for (int r = 0; r < 3; r++)
            d += n[i][r] * (p[i][r] - mean[r]);
        for (int r = 0; r < 3; r++) {
            b[r] += n[i][r] * d;
            for (int c = 0; c < 3; c++)
                a[r][c] += n[i][r] * n[i][c];
        }
    }
    jacobi3(a, v);
    double top = fmax(fabs(a[0][0]), fmax(fabs(a[1][1]), fabs(a[2][2])));
    for (int r = 0; r < 3; r++)
        out[r] = mean[r];
    for (int e = 0; e < 3; e++) {
        if (!(fabs(a[e][e]) > TRUNCATE * top))
            continue;
        double proj = 0;
        for (int r = 0; r < 3; r++)
            proj += v[r][e] * b[r];
        for (int r = 0; r < 3; r++)
            out[r] += v[r][e] * proj / a[e][e];
    }
}

/* ---- pass 1: the vertices ---------------------------------------------------------------- */

/* Edge e of cell (i, j, k) crossing: its point (cell units, from the cell's corner 0, times
 * the spacing) and its unit normal, towards the outside: the gradient of the endpoint whose
 * plane passes nearer the point. Near a sharp edge one endpoint's plane is the face the point
 * lies on and the other's is another face's (or, outside a convex edge, the rounded
 * distance's), and a blend of the two would round the edge off; 0 where the chosen gradient
 * is (the point then only pulls the mean). */
static void hermite(const sdf__signs *s, const float v[8], size_t i, size_t j, size_t k, int e,
                   double p[3], double n[3])
{
    int a, b, axis = e / 4;
    sdf__cell_edge_corners(e, &a, &b);
    double t = sdf__cell_crossing(v[a], v[b]), ga[3], gb[3], len = 0;
    size_t na[3] = {i + (size_t)(a & 1), j + (size_t)(a >> 1 & 1), k + (size_t)(a >> 2 & 1)};
    const double *h = s->v->info.spacing;
    for (int r = 0; r < 3; r++)
        p[r] = (double)(na[r] - (r == 0 ? i : r == 1 ? j : k)) * h[r];
    p[axis] += t * h[axis];
    size_t nb[3] = {na[0], na[1], na[2]};
    nb[axis]++;
    if (!sdf__signs_gradient(s, na[0], na[1], na[2], ga) ||
        !sdf__signs_gradient(s, nb[0], nb[1], nb[2], gb)) {
        n[0] = n[1] = n[2] = 0; /* a cap: its plane is the grid's face */
        n[axis] = v[a] < 0 ? 1 : -1;
        return;
    }
    double ra = fabs(v[a] + ga[axis] * t * h[axis]), rb = fabs(v[b] - gb[axis] * (1 - t) * h[axis]);
    for (int r = 0; r < 3; r++)
        n[r] = ra <= rb ? ga[r] : gb[r], len += n[r] * n[r];
    for (int r = 0; r < 3; r++)
        n[r] = len > 0 ? n[r] / sqrt(len) : 0;
}

static int push_vertex(cell_layer *L, const sdf__signs *s, const double at[3])
{
    if (sdf__grow((void **)&L->pos, &L->pos_cap, 3 * (L->vertices + 1), sizeof(float)))
        return -1;
    sdf__signs_world(s, at, L->pos + 3 * L->vertices++);
    return 0;
}

/* Cell (i, j, k): a vertex per polygon (cell.h), and its record. */
static int do_cell(const sdf__signs *s, cell_layer *L, size_t i, size_t j, size_t k)
{
    float v[8];
    sdf__cell_polys poly;
    for (int c = 0; c < 8; c++)
        v[c] = sdf__signs_value(s, i + (size_t)(c & 1), j + (size_t)(c >> 1 & 1),
                                k + (size_t)(c >> 2 & 1));
    sdf__cell_polygons(v, &poly);
    if (sdf__grow((void **)&L->first, &L->cells_cap, L->cells + 1, sizeof(uint32_t)) ||
        sdf__grow((void **)&L->edges, &L->edges_cap, L->cells + 1, sizeof *L->edges))
        return -1;
    for (int e = 0; e < 12; e++)
        L->edges[L->cells][e] = (uint16_t)((poly.out[e] & 15) | (poly.in[e] & 15) << 4 |
                                           (poly.out_face[e] & 7) << 8);
    L->first[L->cells++] = (uint32_t)L->vertices;
    const double *h = s->v->info.spacing;
    for (int m = 0; m < poly.count; m++) {
        double p[SDF__CELL_MAX_POLY_SIZE][3], n[SDF__CELL_MAX_POLY_SIZE][3], x[3];
        for (int q = 0; q < poly.size[m]; q++)
            hermite(s, v, i, j, k, poly.vert[m][q], p[q], n[q]);
        qef_point((const double (*)[3])p, (const double (*)[3])n, poly.size[m], x);
        double at[3] = {(double)i, (double)j, (double)k};
        for (int r = 0; r < 3; r++)
            at[r] += fmin(fmax(x[r] / h[r], 0), 1); /* clamped to its cell */
        if (push_vertex(L, s, at))
            return -1;
    }
    return 0;
}

static void cell_layers(void *ctx, size_t begin, size_t end, int worker)
{
    job *w = ctx;
    const sdf__signs *s = w->s;
    (void)worker;
    for (size_t k = begin; k < end && !w->failed; k++) {
        cell_layer *L = &w->layers[k];
        for (size_t j = 0; j + 1 < s->n[1]; j++) {
            uint64_t *row = L->active + j * s->words;
            sdf__signs_active(s, j, k, row);
            for (size_t q = 0; q < s->words; q++) {
                L->rank[j * s->words + q] = (uint32_t)L->cells;
                for (uint64_t b = row[q]; b; b &= b - 1)
                    if (do_cell(s, L, q * 64 + (size_t)__builtin_ctzll(b), j, k)) {
                        w->failed = 1;
                        return;
                    }
            }
        }
    }
}

/* ---- pass 2: the quads ------------------------------------------------------------------- */

/* The vertices of cell (i, j, k)'s polygons at its edge e's crossing (the cell is active: e
 * crosses): v[0] the one holding the segment on face f, v[1] the one holding the other
 * segment (the same unless a chord splits the crossing). */
static void vertices_at(const job *w, size_t i, size_t j, size_t k, int e, int f, uint32_t v[2])
{
    const cell_layer *L = &w->layers[k];
    size_t q = j * w->s->words + i / 64;
    uint64_t below = L->active[q] & (((uint64_t)1 << (i % 64)) - 1);
    size_t rank = L->rank[q] + (size_t)sdf__popcount64(below);
    unsigned rec = L->edges[rank][e];
    unsigned out = rec & 15, in = rec >> 4 & 15;
    int on_f = (int)(rec >> 8 & 7) == f;
    uint32_t base = (uint32_t)(w->first[k] + L->first[rank]);
    v[0] = base + (on_f ? out : in), v[1] = base + (on_f ? in : out);
}

static double area2(const float *v, uint32_t a, uint32_t b, uint32_t c)
{
    double u[3], x[3];
    for (int r = 0; r < 3; r++)
        u[r] = v[3 * b + r] - v[3 * a + r], x[r] = v[3 * c + r] - v[3 * a + r];
    double n[3] = {u[1] * x[2] - u[2] * x[1], u[2] * x[0] - u[0] * x[2], u[0] * x[1] - u[1] * x[0]};
    return n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
}

/* The dual face q[0..n-1] (counter-clockwise seen from outside, 4 <= n <= 8) as triangles.
 * A quad: split along the diagonal whose smaller triangle is larger (its corners' cells meet
 * only at this edge, so no other face can draw that diagonal). A larger face (a chord split
 * the crossing): a fan from a new vertex at the crossing itself, on the surface, so that no
 * diagonal of it can be an edge of another face. */
static int push_face(cell_layer *out, const float *vertices, const uint32_t *q, int n,
                     const float crossing[3])
{
    uint32_t t[3 * 8];
    int nt = 0;
    if (n == 4) {
        double a = fmin(area2(vertices, q[0], q[1], q[2]), area2(vertices, q[0], q[2], q[3]));
        double b = fmin(area2(vertices, q[1], q[2], q[3]), area2(vertices, q[1], q[3], q[0]));
        int d = b > a;
        uint32_t two[6] = {q[d], q[d + 1], q[d + 2], q[d], q[d + 2], q[(d + 3) & 3]};
        memcpy(t, two, sizeof two);
        nt = 2;
    } else {
        if (sdf__grow((void **)&out->extra, &out->extra_cap, 3 * (out->extras + 1),
                      sizeof(float)))
            return -1;
        memcpy(out->extra + 3 * out->extras, crossing, 3 * sizeof(float));
        uint32_t center = EXTRA_BIT | (uint32_t)out->extras++;
        for (int i = 0; i < n; i++, nt++)
            t[3 * nt] = center, t[3 * nt + 1] = q[i], t[3 * nt + 2] = q[(i + 1) % n];
    }
    if (sdf__grow((void **)&out->tri, &out->tri_cap, 3 * (out->tris + (size_t)nt),
                  sizeof(uint32_t)))
        return -1;
    memcpy(out->tri + 3 * out->tris, t, (size_t)nt * 3 * sizeof(uint32_t));
    out->tris += (size_t)nt;
    return 0;
}

/* The four cells around the crossing edge from node (i, j, k) along axis, counter-clockwise
 * seen from the axis's positive side, each as (i, j, k, its edge number for this edge, the
 * face it shares with the cell before it). 0 when the edge lies on the grid's boundary. */
static int around(const sdf__signs *s, int axis, size_t i, size_t j, size_t k, size_t c[4][5])
{
    static const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
    size_t at[3] = {i, j, k};
    int u = axis == 0 ? 1 : axis == 1 ? 2 : 0, v = axis == 0 ? 2 : axis == 1 ? 0 : 1;
    const int shared[4] = {2 * v + 1, 2 * u, 2 * v, 2 * u + 1}; /* towards cell m - 1 */
    if (at[u] == 0 || at[v] == 0 || at[u] + 1 >= s->n[u] || at[v] + 1 >= s->n[v])
        return 0;
    for (int m = 0; m < 4; m++) {
        size_t cell[3] = {i, j, k};
        cell[u] = at[u] - 1 + (size_t)du[m], cell[v] = at[v] - 1 + (size_t)dv[m];
        int off[3] = {0, 0, 0};
        off[u] = 1 - du[m], off[v] = 1 - dv[m]; /* the edge's place in that cell */
        int e = axis == 0 ? off[1] + 2 * off[2] : axis == 1 ? 4 + off[0] + 2 * off[2]
                                                            : 8 + off[0] + 2 * off[1];
        c[m][0] = cell[0], c[m][1] = cell[1], c[m][2] = cell[2], c[m][3] = (size_t)e;
        c[m][4] = (size_t)shared[m];
    }
    return 1;
}

/* The dual face of a crossing edge: in each of its four cells, the polygon on the face shared
 * with the cell before, then the other one there is when a chord splits the crossing. */
static int do_edge(job *w, const float *vertices, int axis, size_t i, size_t j, size_t k,
                   cell_layer *out)
{
    size_t c[4][5];
    if (!around(w->s, axis, i, j, k, c))
        return 0;
    uint32_t q[8];
    int n = 0;
    for (int m = 0; m < 4; m++) {
        uint32_t v[2];
        vertices_at(w, c[m][0], c[m][1], c[m][2], (int)c[m][3], (int)c[m][4], v);
        q[n++] = v[0];
        if (v[1] != v[0])
            q[n++] = v[1];
    }
    float lo = sdf__signs_value(w->s, i, j, k);
    size_t hi[3] = {i, j, k};
    hi[axis]++;
    if (!(lo < 0)) /* the inside is on the positive side */
        for (int a = 0, b = n - 1; a < b; a++, b--) {
            uint32_t t = q[a];
            q[a] = q[b], q[b] = t;
        }
    double at[3] = {(double)i, (double)j, (double)k};
    float crossing[3];
    at[axis] += sdf__cell_crossing(lo, sdf__signs_value(w->s, hi[0], hi[1], hi[2]));
    sdf__signs_world(w->s, at, crossing);
    return push_face(out, vertices, q, n, crossing);
}

static void node_layers(void *ctx, size_t begin, size_t end, int worker)
{
    job *w = ctx;
    const sdf__signs *s = w->s;
    const float *vertices = w->vertices;
    uint64_t *row = w->rows + (size_t)worker * s->words;
    for (size_t k = begin; k < end && !w->failed; k++)
        for (int axis = 0; axis < 3 && !(axis == 2 && k + 1 == s->n[2]); axis++) {
            size_t rows = axis == 1 ? s->n[1] - 1 : s->n[1];
            for (size_t j = 0; j < rows; j++) {
                sdf__signs_cross(s, axis, j, k, row);
                for (size_t q = 0; q < s->words; q++)
                    for (uint64_t b = row[q]; b; b &= b - 1)
                        if (do_edge(w, vertices, axis, q * 64 + (size_t)__builtin_ctzll(b), j,
                                    k, &w->layers[k])) {
                            w->failed = 1;
                            return;
                        }
            }
        }
}

/* ---- the call ---------------------------------------------------------------------------- */

static int alloc_layers(job *w)
{
    const sdf__signs *s = w->s;
    size_t words = s->n[1] * s->words;
    if (!(w->layers = calloc(s->n[2], sizeof *w->layers)) ||
        !(w->first = calloc(s->n[2] + 1, sizeof *w->first)))
        return SDF_ENOMEM;
    for (size_t k = 0; k + 1 < s->n[2]; k++)
        if (!(w->layers[k].active = malloc(words * sizeof(uint64_t))) ||
            !(w->layers[k].rank = malloc(words * sizeof(uint32_t))))
            return SDF_ENOMEM;
    return 0;
}

static void free_layers(job *w)
{
    for (size_t k = 0; w->layers && k < w->s->n[2]; k++) {
        cell_layer *L = &w->layers[k];
        free(L->active), free(L->rank), free(L->first), free(L->edges), free(L->pos);
        free(L->tri), free(L->extra);
    }
    free(w->layers), free(w->first), free(w->rows), free(w->vertices);
}

/* The vertices of every cell layer, in order, into w->vertices. */
static int join_vertices(job *w)
{
    size_t n2 = w->s->n[2];
    for (size_t k = 0; k + 1 < n2; k++)
        w->first[k + 1] = w->first[k] + w->layers[k].vertices;
    if (w->first[n2 - 1] >= MAX_VERTICES)
        return SDF_ELIMIT;
    if (!(w->vertices = malloc((size_t)w->first[n2 - 1] * 3 * sizeof(float) + 1)))
        return SDF_ENOMEM;
    for (size_t k = 0; k + 1 < n2; k++)
        if (w->layers[k].vertices) /* a layer without any has no array (NULL) */
            memcpy(w->vertices + 3 * w->first[k], w->layers[k].pos,
                   w->layers[k].vertices * 3 * sizeof(float));
    return 0;
}

/* Every node layer's triangles, in order, with the extra vertices after the cells' (also in
 * layer order). */
static int join_triangles(job *w, sdf_surface *out)
{
    size_t n2 = w->s->n[2], tris = 0, extras = 0, at = 0;
    size_t cells = (size_t)w->first[n2 - 1];
    for (size_t k = 0; k < n2; k++)
        tris += w->layers[k].tris, extras += w->layers[k].extras;
    if (cells + extras >= MAX_VERTICES)
        return SDF_ELIMIT;
    float *v = realloc(w->vertices, (cells + extras) * 3 * sizeof(float) + 1);
    if (!v || !(out->triangles = malloc(tris * 3 * sizeof(uint32_t) + 1))) {
        if (v)
            w->vertices = v;
        return SDF_ENOMEM;
    }
    w->vertices = v;
    for (size_t k = 0, next = cells; k < n2; k++) {
        const cell_layer *L = &w->layers[k];
        if (L->extras) /* a layer without any has no array (NULL) */
            memcpy(v + 3 * next, L->extra, L->extras * 3 * sizeof(float));
        for (size_t q = 0; q < 3 * L->tris; q++)
            out->triangles[at + q] = L->tri[q] & EXTRA_BIT
                                         ? (uint32_t)(next + (L->tri[q] & ~EXTRA_BIT))
                                         : L->tri[q];
        at += 3 * L->tris, next += L->extras;
    }
    out->triangle_count = tris;
    out->vertices = v, out->vertex_count = cells + extras;
    w->vertices = NULL;
    return 0;
}

int sdf__dual_extract(const sdf__signs *s, int threads, sdf_surface *out)
{
    size_t n2 = s->n[2];
    size_t chunk = n2 / (8 * (size_t)sdf__effective_threads(threads, n2, 1));
    chunk = chunk ? chunk : 1;
    int workers = sdf__effective_threads(threads, n2, chunk);
    job w = {.s = s};
    int rc = alloc_layers(&w);
    if (!rc) {
        sdf__parallel_for(n2 - 1, chunk, workers, cell_layers, &w);
        rc = w.failed ? SDF_ENOMEM : join_vertices(&w);
    }
    if (!rc && !(w.rows = malloc((size_t)workers * s->words * sizeof(uint64_t))))
        rc = SDF_ENOMEM;
    if (!rc) {
        sdf__parallel_for(n2, chunk, workers, node_layers, &w);
        rc = w.failed ? SDF_ENOMEM : join_triangles(&w, out);
    }
    free_layers(&w);
    return rc;
}
