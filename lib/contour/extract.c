/* extract.c - sdf_volume_extract (sdf.h, "Surfaces of volumes"): marching cubes over a
 * volume's nodes, one cell at a time by cell.h's face rule, numbering everything in layer
 * order so that the arrays do not depend on the thread count:
 *  0. the nodes' sides as bits (signs.h): the one pass that reads every value;
 *  1. per node layer, from the bits alone: how many of its x-edges, y-edges and z-edges (up
 *     to the next layer) cross, whose prefix sums give each layer's first vertex;
 *  2. per cell layer: index its two node layers' crossings (the id of a crossing is its
 *     row word's first id plus a popcount), place the lower layer's vertices (reading the
 *     two values of each crossing edge), and triangulate the cells whose corners differ
 *     (reading their eight values) into the layer's own list.
 * The lists are then joined in layer order, and the loops' centroids that cell.h added
 * (rare: ambiguous faces) go after the edges' vertices, also in layer order. Dual contouring
 * (dual.h) starts from the same bits and is chosen here. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contour/cell.h"
#include "contour/dual.h"
#include "contour/signs.h"
#include "contour/surface.h"
#include "core/diag.h"
#include "core/grow.h"
#include "core/parallel.h"
#include "volume/volume.h"

#define CENTROID_BIT 0x80000000u /* in a layer's list: a centroid of that layer's */
#define MAX_VERTICES ((uint64_t)1 << 31)

typedef struct layer_out {
    uint32_t *tri;      /* 3 per triangle: vertex ids, or CENTROID_BIT | centroid */
    size_t tris, tri_cap;
    float *centroid;    /* 3 per centroid */
    size_t centroids, centroid_cap;
} layer_out;

/* The crossing edges of one family (x, y or z) of one node layer, indexed. */
typedef struct family {
    uint64_t *cross;    /* a row of words per row of nodes (signs.h) */
    uint32_t *first;    /* per word: the id of its first crossing */
} family;

enum { X_LO, Y_LO, Z_LO, X_HI, Y_HI, FAMILIES };

typedef struct scratch {
    family f[FAMILIES]; /* of node layers k (LO) and k + 1 (HI) of the cell layer at hand */
    uint64_t *active;   /* one row of cells */
} scratch;

typedef struct job {
    sdf__signs s;
    uint64_t *first;    /* per node layer: its first vertex id (n[2] + 1 entries) */
    uint64_t *count;    /* per node layer: its crossings */
    float *vertices;
    layer_out *layers;
    scratch *scratch;   /* per worker */
    int failed;         /* a worker ran out of memory */
} job;


/* ---- pass 1 ----------------------------------------------------------------------------- */

static uint64_t popcount_row(const uint64_t *row, size_t words)
{
    uint64_t c = 0;
    for (size_t w = 0; w < words; w++)
        c += (uint64_t)sdf__popcount64(row[w]);
    return c;
}

/* Node layer k's crossings: its x-edges, y-edges, then z-edges (the order of pass 2). */
static uint64_t count_layer(const sdf__signs *s, size_t k, uint64_t *row)
{
    uint64_t c = 0;
    for (int axis = 0; axis < 3; axis++) {
        size_t rows = axis == 1 ? s->n[1] - 1 : s->n[1];
        if (axis == 2 && k + 1 == s->n[2])
            break;
        for (size_t j = 0; j < rows; j++) {
            sdf__signs_cross(s, axis, j, k, row);
            c += popcount_row(row, s->words);
        }
    }
    return c;
}

static void count_layers(void *ctx, size_t begin, size_t end, int worker)
{
    job *w = ctx;
    for (size_t k = begin; k < end; k++)
        w->count[k] = count_layer(&w->s, k, w->scratch[worker].active);
}

/* ---- pass 2 ----------------------------------------------------------------------------- */

static void place(job *w, uint64_t id, size_t i, size_t j, size_t k, int axis)
{
    size_t n[3] = {i, j, k};
    n[axis]++;
    double cell[3] = {(double)i, (double)j, (double)k};
    cell[axis] += sdf__cell_crossing(sdf__signs_value(&w->s, i, j, k),
                             sdf__signs_value(&w->s, n[0], n[1], n[2]));
    sdf__signs_world(&w->s, cell, w->vertices + 3 * id);
}

/* Index one family of node layer k from `id` (placing its vertices when asked); returns the
 * next id. */
static uint64_t index_family(job *w, family *f, int axis, size_t k, uint64_t id, int placing)
{
    size_t words = w->s.words, rows = axis == 1 ? w->s.n[1] - 1 : w->s.n[1];
    for (size_t j = 0; j < rows; j++) {
        uint64_t *row = f->cross + j * words;
        sdf__signs_cross(&w->s, axis, j, k, row);
        for (size_t q = 0; q < words; q++) {
            f->first[j * words + q] = (uint32_t)id;
            for (uint64_t b = row[q]; placing && b; b &= b - 1)
                place(w, id + (uint64_t)sdf__popcount64(row[q] & ((b & -b) - 1)),
                      q * 64 + (size_t)__builtin_ctzll(b), j, k, axis);
            id += (uint64_t)sdf__popcount64(row[q]);
        }
    }
    return id;
}

/* Index node layers k and k + 1; place layer k's vertices (and k + 1's when it is the top,
 * which has no cell layer of its own). */
static void index_layers(job *w, scratch *s, size_t k)
{
    int top = k + 2 == w->s.n[2];
    uint64_t id = index_family(w, &s->f[X_LO], 0, k, w->first[k], 1);
    id = index_family(w, &s->f[Y_LO], 1, k, id, 1);
    index_family(w, &s->f[Z_LO], 2, k, id, 1);
    id = index_family(w, &s->f[X_HI], 0, k + 1, w->first[k + 1], top);
    index_family(w, &s->f[Y_HI], 1, k + 1, id, top);
}

/* The id of cell (i, j)'s crossing on edge e. */
static uint32_t edge_id(const scratch *s, size_t words, size_t i, size_t j, int e)
{
    int a, b, axis = e / 4;
    sdf__cell_edge_corners(e, &a, &b);
    const family *f = &s->f[axis == 2 ? Z_LO : axis + 3 * (a >> 2 & 1)];
    size_t x = i + (size_t)(a & 1), q = (j + (size_t)(a >> 1 & 1)) * words + x / 64;
    uint64_t below = f->cross[q] & (((uint64_t)1 << (x % 64)) - 1);
    return f->first[q] + (uint32_t)sdf__popcount64(below);
}

static int push_centroid(job *w, layer_out *out, const double at[3], const double cr[12][3],
                         const uint8_t *edges, int n)
{
    if (sdf__grow((void **)&out->centroid, &out->centroid_cap, 3 * (out->centroids + 1),
                  sizeof(float)))
        return -1;
    double cell[3];
    for (int a = 0; a < 3; a++) {
        double sum = 0;
        for (int m = 0; m < n; m++)
            sum += cr[edges[m]][a];
        cell[a] = at[a] + sum / n;
    }
    sdf__signs_world(&w->s, cell, out->centroid + 3 * out->centroids++);
    return 0;
}

/* Cell (i, j) of layer k: its triangles onto out. */
static int do_cell(job *w, const scratch *s, size_t i, size_t j, size_t k, layer_out *out)
{
    float v[8];
    double cr[12][3], at[3] = {(double)i, (double)j, (double)k};
    for (int c = 0; c < 8; c++)
        v[c] = sdf__signs_value(&w->s, i + (size_t)(c & 1), j + (size_t)(c >> 1 & 1),
                                k + (size_t)(c >> 2 & 1));
    for (int e = 0; e < 12; e++) {
        int a, b;
        sdf__cell_edge_corners(e, &a, &b);
        if ((v[a] < 0) == (v[b] < 0))
            continue;
        cr[e][0] = a & 1, cr[e][1] = a >> 1 & 1, cr[e][2] = a >> 2 & 1;
        cr[e][e / 4] += sdf__cell_crossing(v[a], v[b]);
    }
    sdf__cell_out co;
    int nt = sdf__cell_triangulate(v, cr, w->s.v->info.spacing, &co);
    size_t base = out->centroids;
    for (int m = 0; m < co.centroids; m++)
        if (push_centroid(w, out, at, cr, co.centroid_edges[m], co.centroid_count[m]))
            return -1;
    if (sdf__grow((void **)&out->tri, &out->tri_cap, 3 * (out->tris + (size_t)nt),
                  sizeof(uint32_t)))
        return -1;
    for (int t = 0; t < nt; t++, out->tris++)
        for (int c = 0; c < 3; c++) {
            int x = co.tri[t][c];
            out->tri[3 * out->tris + (size_t)c] =
                x >= SDF__CELL_CENTROID
                    ? CENTROID_BIT | (uint32_t)(base + (size_t)(x - SDF__CELL_CENTROID))
                    : edge_id(s, w->s.words, i, j, x);
        }
    return 0;
}

static void cell_layers(void *ctx, size_t begin, size_t end, int worker)
{
    job *w = ctx;
    scratch *s = &w->scratch[worker];
    for (size_t k = begin; k < end && !w->failed; k++) {
        index_layers(w, s, k);
        for (size_t j = 0; j + 1 < w->s.n[1]; j++) {
            sdf__signs_active(&w->s, j, k, s->active);
            for (size_t q = 0; q < w->s.words; q++)
                for (uint64_t b = s->active[q]; b; b &= b - 1)
                    if (do_cell(w, s, q * 64 + (size_t)__builtin_ctzll(b), j, k,
                                &w->layers[k])) {
                        w->failed = 1;
                        return;
                    }
        }
    }
}

/* ---- the call ---------------------------------------------------------------------------- */

static void free_scratch(scratch *s, int workers)
{
    for (int t = 0; s && t < workers; t++) {
        for (int f = 0; f < FAMILIES; f++)
            free(s[t].f[f].cross), free(s[t].f[f].first);
        free(s[t].active);
    }
    free(s);
}

static scratch *alloc_scratch(const sdf__signs *g, int workers)
{
    size_t words = g->n[1] * g->words;
    scratch *s = calloc((size_t)workers, sizeof *s);
    int ok = s != NULL;
    for (int t = 0; ok && t < workers; t++) {
        for (int f = 0; ok && f < FAMILIES; f++)
            ok = (s[t].f[f].cross = malloc(words * sizeof(uint64_t))) &&
                 (s[t].f[f].first = malloc(words * sizeof(uint32_t)));
        ok = ok && (s[t].active = malloc(g->words * sizeof(uint64_t)));
    }
    if (!ok) {
        free_scratch(s, workers);
        return NULL;
    }
    return s;
}

/* Join the layers' lists: edge vertices first, then every layer's centroids in order. */
static int join(job *w, size_t layers, uint64_t edges, sdf_surface *out)
{
    size_t tris = 0, centroids = 0;
    for (size_t k = 0; k < layers; k++)
        tris += w->layers[k].tris, centroids += w->layers[k].centroids;
    if (edges + centroids >= MAX_VERTICES)
        return SDF_ELIMIT;
    float *vert = realloc(w->vertices, (size_t)(edges + centroids) * 3 * sizeof(float) + 1);
    uint32_t *tri = malloc(tris * 3 * sizeof(uint32_t) + 1);
    if (vert)
        w->vertices = vert;
    if (!vert || !tri) {
        free(tri);
        return SDF_ENOMEM;
    }
    size_t c0 = (size_t)edges, t0 = 0;
    for (size_t k = 0; k < layers; k++) {
        const layer_out *L = &w->layers[k];
        if (L->centroids) /* memcpy's NULL source is undefined even for no bytes */
            memcpy(vert + 3 * c0, L->centroid, L->centroids * 3 * sizeof(float));
        for (size_t q = 0; q < 3 * L->tris; q++)
            tri[t0 + q] = L->tri[q] & CENTROID_BIT ? (uint32_t)(c0 + (L->tri[q] & ~CENTROID_BIT))
                                                   : L->tri[q];
        c0 += L->centroids, t0 += 3 * L->tris;
    }
    out->vertices = vert, out->vertex_count = (size_t)(edges + centroids);
    out->triangles = tri, out->triangle_count = tris;
    w->vertices = NULL;
    return 0;
}

static void release(job *w, int workers, size_t layers)
{
    free_scratch(w->scratch, workers);
    for (size_t k = 0; w->layers && k < layers; k++)
        free(w->layers[k].tri), free(w->layers[k].centroid);
    free(w->layers), free(w->count), free(w->first), free(w->vertices);
    sdf__signs_free(&w->s);
}

/* Both passes after the bits; *out filled on 0. */
static int passes(job *w, int workers, size_t chunk, sdf_surface *out)
{
    size_t n2 = w->s.n[2];
    sdf__parallel_for(n2, chunk, workers, count_layers, w);
    for (size_t k = 0; k < n2; k++)
        w->first[k + 1] = w->first[k] + w->count[k];
    if (w->first[n2] >= MAX_VERTICES)
        return SDF_ELIMIT;
    if (!(w->vertices = malloc((size_t)w->first[n2] * 3 * sizeof(float) + 1)))
        return SDF_ENOMEM;
    sdf__parallel_for(n2 - 1, chunk, workers, cell_layers, w);
    return w->failed ? SDF_ENOMEM : join(w, n2 - 1, w->first[n2], out);
}

static int run(job *w, int threads, int dual, sdf_surface *out, sdf_diag *diag)
{
    int rc = sdf__signs_fill(&w->s, threads);
    if (!rc && dual) {
        rc = sdf__dual_extract(&w->s, threads, out);
        sdf__signs_free(&w->s);
        return rc ? sdf__diag_set(diag, rc, 0, -1, rc == SDF_ELIMIT
                                  ? "the surface has more than 2^31 vertices"
                                  : "out of memory extracting the surface") : 0;
    }
    size_t n2 = w->s.n[2];
    size_t chunk = n2 / (8 * (size_t)sdf__effective_threads(threads, n2, 1));
    chunk = chunk ? chunk : 1;
    int workers = sdf__effective_threads(threads, n2, chunk);
    if (!rc) {
        w->scratch = alloc_scratch(&w->s, workers);
        w->count = calloc(n2, sizeof *w->count);
        w->first = calloc(n2 + 1, sizeof *w->first);
        w->layers = calloc(n2, sizeof *w->layers);
        rc = w->scratch && w->count && w->first && w->layers ? 0 : SDF_ENOMEM;
    }
    if (!rc)
        rc = passes(w, workers, chunk, out);
    release(w, workers, n2);
    if (rc == SDF_ELIMIT)
        return sdf__diag_set(diag, rc, 0, -1, "the surface has more than 2^31 vertices");
    return rc ? sdf__diag_set(diag, rc, 0, -1, "out of memory extracting the surface") : 0;
}

int sdf_volume_extract(const sdf_volume *volume, const sdf_extract_options *opts,
                       sdf_surface **out, sdf_diag *diag)
{
    static const sdf_extract_options defaults;
    sdf__diag_clear(diag);
    if (!volume || !out)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "no volume or output pointer");
    *out = NULL;
    opts = opts ? opts : &defaults;
    if (!isfinite(opts->iso))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "iso must be a finite number");
    if ((unsigned)opts->method > SDF_EXTRACT_DUAL)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown extraction method %d",
                             (int)opts->method);
    int dual = opts->method == SDF_EXTRACT_DUAL ||
               (opts->method == SDF_EXTRACT_AUTO && volume->info.order == 1);
    job w = {.s = {.v = volume, .iso = opts->iso, .pad = opts->cap != 0}};
    sdf_surface *s = calloc(1, sizeof *s);
    if (!s)
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of memory");
    int rc = run(&w, opts->threads, dual, s, diag);
    if (rc) {
        free(s);
        return rc;
    }
    *out = s;
    return 0;
}
