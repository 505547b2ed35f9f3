/* extract.c - sdf_volume_extract (sdf.h, "Surfaces of volumes"): marching cubes over a
 * volume's nodes, one cell at a time by cell.h's face rule, in two passes over z-layers that
 * run on any number of threads and number everything in layer order, so that the arrays do
 * not depend on the thread count:
 *  1. count the crossing edges of each node layer (its x-edges, its y-edges, and the z-edges
 *     up to the next layer), whose prefix sums give each layer's first vertex;
 *  2. per cell layer: number its two node layers' crossings as pass 1 ordered them, place
 *     the vertices of the lower layer, and triangulate its cells into the layer's own list.
 * The lists are then joined in layer order, and the loops' centroids that cell.h added
 * (rare: ambiguous faces) go after the edges' vertices, also in layer order.
 *
 * Node values live only as the two layers a worker is at, relative to iso: a first-order
 * volume's are its planes evaluated at the nodes, and with caps the grid grows by one node
 * on every side whose value counts as outside. A cell whose eight corners agree costs eight
 * comparisons, which is all the narrow band's absence costs. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contour/cell.h"
#include "core/diag.h"
#include "core/grow.h"
#include "core/parallel.h"
#include "volume/volume.h"

#define OUTSIDE 1e30f            /* the value of the nodes beyond the grid, with caps */
#define EDGE_MARGIN 1e-3         /* a vertex's least distance from a node, in cells */
#define CENTROID_BIT 0x80000000u /* in a layer's list: a centroid of that layer's */
#define MAX_VERTICES ((uint64_t)1 << 31)

struct sdf_surface {
    float *vertices;
    uint32_t *triangles;
    size_t vertex_count, triangle_count;
};

typedef struct grid {
    const sdf_volume *v;
    double iso;
    int pad;            /* 1 with caps: a node of outside all around */
    size_t n[3];        /* nodes per axis, the padding included */
} grid;

typedef struct layer_out {
    uint32_t *tri;      /* 3 per triangle: vertex ids, or CENTROID_BIT | centroid */
    size_t tris, tri_cap;
    float *centroid;    /* 3 per centroid */
    size_t centroids, centroid_cap;
} layer_out;

typedef struct scratch {
    float *values[2];   /* node layers lo and lo + 1 */
    size_t lo;          /* which layers values[] hold; SIZE_MAX: none */
    uint32_t *map[5];   /* crossing ids: x, y, z of layer lo; x, y of layer lo + 1 */
} scratch;

typedef struct job {
    grid g;
    uint64_t *first;    /* per node layer: its first vertex id (n[2] + 1 entries) */
    uint64_t *count;    /* per node layer: x, y and z crossings */
    float *vertices;
    layer_out *layers;
    scratch *scratch;   /* per worker */
    int failed;         /* a worker ran out of memory */
} job;

/* ---- node values ------------------------------------------------------------------------ */

static double node_value(const grid *g, size_t i, size_t j, size_t k)
{
    const sdf_volume *v = g->v;
    size_t idx = (k * v->info.dims[1] + j) * v->info.dims[0] + i;
    if (v->info.order == 0)
        return v->data.f[idx];
    double plane[4], at[3];
    sdf__volume_node_plane(v, i, j, k, plane);
    sdf__volume_node(&v->info, i, j, k, at);
    return plane[0] * at[0] + plane[1] * at[1] + plane[2] * at[2] + plane[3];
}

/* Node layer k's values relative to iso, x fastest. */
static void load_layer(const grid *g, size_t k, float *out)
{
    size_t n0 = g->n[0], n1 = g->n[1], p = (size_t)g->pad;
    for (size_t j = 0; j < n1; j++)
        for (size_t i = 0; i < n0; i++) {
            int beyond = p && (i == 0 || j == 0 || k == 0 || i == n0 - 1 || j == n1 - 1 ||
                               k == g->n[2] - 1);
            out[j * n0 + i] = beyond ? OUTSIDE
                                     : (float)(node_value(g, i - p, j - p, k - p) - g->iso);
        }
}

static int crosses(float a, float b)
{
    return (a < 0) != (b < 0);
}

/* Where along an edge from value a to value b the crossing is, in (0, 1). */
static double crossing_t(float a, float b)
{
    double t = (double)a / ((double)a - b);
    return t < EDGE_MARGIN ? EDGE_MARGIN : t > 1 - EDGE_MARGIN ? 1 - EDGE_MARGIN : t;
}

/* ---- numbering: the order both passes share ---------------------------------------------- */

/* What a numbering of node layer k stores besides counting: the ids of its crossings
 * (maps not NULL), and their positions (vertices not NULL). */
typedef struct numbering {
    const grid *g;
    size_t k;
    uint32_t *mx, *my, *mz;
    float *vertices;
} numbering;

static void place(const numbering *nb, uint64_t id, size_t i, size_t j, int axis, double t)
{
    const sdf_volume_info *in = &nb->g->v->info;
    double cell[3] = {(double)i, (double)j, (double)nb->k};
    cell[axis] += t;
    for (int a = 0; a < 3; a++)
        nb->vertices[3 * id + (size_t)a] =
            (float)(in->origin[a] + (cell[a] - nb->g->pad) * in->spacing[a]);
}

/* One crossing edge from node (i, j) along axis, values a then b: its id, stored as asked. */
static uint64_t take(const numbering *nb, uint64_t id, uint32_t *map, size_t q, size_t i,
                     size_t j, int axis, float a, float b)
{
    if (map)
        map[q] = (uint32_t)id;
    if (nb->vertices)
        place(nb, id, i, j, axis, crossing_t(a, b));
    return id + 1;
}

/* Number layer L's crossing x-edges, then its y-edges, from `id`. Returns the next id. */
static uint64_t number_xy(const numbering *nb, const float *L, uint64_t id)
{
    size_t n0 = nb->g->n[0], n1 = nb->g->n[1];
    for (size_t j = 0; j < n1; j++)
        for (size_t i = 0; i + 1 < n0; i++) {
            float a = L[j * n0 + i], b = L[j * n0 + i + 1];
            if (crosses(a, b))
                id = take(nb, id, nb->mx, j * n0 + i, i, j, 0, a, b);
        }
    for (size_t j = 0; j + 1 < n1; j++)
        for (size_t i = 0; i < n0; i++) {
            float a = L[j * n0 + i], b = L[(j + 1) * n0 + i];
            if (crosses(a, b))
                id = take(nb, id, nb->my, j * n0 + i, i, j, 1, a, b);
        }
    return id;
}

/* The z-edges from layer L0 up to L1, likewise. */
static uint64_t number_z(const numbering *nb, const float *L0, const float *L1, uint64_t id)
{
    size_t n0 = nb->g->n[0], nodes = n0 * nb->g->n[1];
    for (size_t q = 0; q < nodes; q++)
        if (crosses(L0[q], L1[q]))
            id = take(nb, id, nb->mz, q, q % n0, q / n0, 2, L0[q], L1[q]);
    return id;
}

/* Make sure the worker's values[] hold layers k and k + 1 (reusing the upper one when it
 * moves up by one). */
static void hold_layers(const grid *g, scratch *s, size_t k)
{
    if (s->lo == k)
        return;
    if (s->lo != SIZE_MAX && s->lo + 1 == k) {
        float *t = s->values[0];
        s->values[0] = s->values[1], s->values[1] = t;
    } else {
        load_layer(g, k, s->values[0]);
    }
    if (k + 1 < g->n[2])
        load_layer(g, k + 1, s->values[1]);
    s->lo = k;
}

/* ---- pass 1 ----------------------------------------------------------------------------- */

static void count_layers(void *ctx, size_t begin, size_t end, int worker)
{
    job *w = ctx;
    scratch *s = &w->scratch[worker];
    for (size_t k = begin; k < end; k++) {
        numbering nb = {.g = &w->g, .k = k};
        hold_layers(&w->g, s, k);
        uint64_t c = number_xy(&nb, s->values[0], 0);
        if (k + 1 < w->g.n[2])
            c = number_z(&nb, s->values[0], s->values[1], c);
        w->count[k] = c;
    }
}

/* ---- pass 2 ----------------------------------------------------------------------------- */

/* Number (and, for the lower one, place) the crossings of node layers k and k + 1. */
static void number_layers(job *w, scratch *s, size_t k)
{
    numbering lower = {&w->g, k, s->map[0], s->map[1], s->map[2], w->vertices};
    number_z(&lower, s->values[0], s->values[1], number_xy(&lower, s->values[0], w->first[k]));
    /* the top layer has no cell layer of its own: the one below places it */
    numbering upper = {&w->g, k + 1, s->map[3], s->map[4], NULL,
                       k + 2 == w->g.n[2] ? w->vertices : NULL};
    number_xy(&upper, s->values[1], w->first[k + 1]);
}

/* The global id of cell (i, j)'s crossing on edge e. */
static uint32_t edge_id(const scratch *s, size_t n0, size_t i, size_t j, int e)
{
    int a, b, axis = e / 4;
    sdf__cell_edge_corners(e, &a, &b);
    size_t q = (j + (size_t)(a >> 1 & 1)) * n0 + i + (size_t)(a & 1);
    int up = a >> 2 & 1;
    return s->map[axis == 2 ? 2 : axis + 3 * up][q];
}

static int push_centroid(job *w, layer_out *out, size_t i, size_t j, size_t k,
                         const double cr[12][3], const uint8_t *edges, int n)
{
    const sdf_volume_info *in = &w->g.v->info;
    if (sdf__grow((void **)&out->centroid, &out->centroid_cap, 3 * (out->centroids + 1),
                  sizeof(float)))
        return -1;
    double cell[3] = {(double)i, (double)j, (double)k}, sum[3] = {0, 0, 0};
    for (int m = 0; m < n; m++)
        for (int a = 0; a < 3; a++)
            sum[a] += cr[edges[m]][a];
    for (int a = 0; a < 3; a++)
        out->centroid[3 * out->centroids + (size_t)a] =
            (float)(in->origin[a] + (cell[a] + sum[a] / n - w->g.pad) * in->spacing[a]);
    out->centroids++;
    return 0;
}

/* Cell (i, j) of layer k, whose corner values are v: its triangles onto out. */
static int do_cell(job *w, const scratch *s, size_t i, size_t j, size_t k, const float v[8],
                   layer_out *out)
{
    double cr[12][3];
    for (int e = 0; e < 12; e++) {
        int a, b;
        sdf__cell_edge_corners(e, &a, &b);
        if (!crosses(v[a], v[b]))
            continue;
        cr[e][0] = a & 1, cr[e][1] = a >> 1 & 1, cr[e][2] = a >> 2 & 1;
        cr[e][e / 4] += crossing_t(v[a], v[b]);
    }
    sdf__cell_out co;
    int nt = sdf__cell_triangulate(v, cr, w->g.v->info.spacing, &co);
    size_t base = out->centroids;
    for (int m = 0; m < co.centroids; m++)
        if (push_centroid(w, out, i, j, k, cr, co.centroid_edges[m], co.centroid_count[m]))
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
                    : edge_id(s, w->g.n[0], i, j, x);
        }
    return 0;
}

/* The values at cell (i, j)'s corners (cell.h's numbering) of the layers held. */
static void corners(const scratch *s, size_t n0, size_t i, size_t j, float v[8])
{
    for (int c = 0; c < 8; c++)
        v[c] = s->values[c >> 2][(j + (size_t)(c >> 1 & 1)) * n0 + i + (size_t)(c & 1)];
}

static void cell_layers(void *ctx, size_t begin, size_t end, int worker)
{
    job *w = ctx;
    scratch *s = &w->scratch[worker];
    size_t n0 = w->g.n[0], n1 = w->g.n[1];
    for (size_t k = begin; k < end && !w->failed; k++) {
        hold_layers(&w->g, s, k);
        number_layers(w, s, k);
        for (size_t j = 0; j + 1 < n1; j++)
            for (size_t i = 0; i + 1 < n0; i++) {
                float v[8];
                corners(s, n0, i, j, v);
                int inside = 0;
                for (int c = 0; c < 8; c++)
                    inside += v[c] < 0;
                if (inside % 8 && do_cell(w, s, i, j, k, v, &w->layers[k])) {
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
        free(s[t].values[0]), free(s[t].values[1]);
        for (int m = 0; m < 5; m++)
            free(s[t].map[m]);
    }
    free(s);
}

static scratch *alloc_scratch(const grid *g, int workers)
{
    size_t nodes = g->n[0] * g->n[1];
    scratch *s = calloc((size_t)workers, sizeof *s);
    int ok = s != NULL;
    for (int t = 0; ok && t < workers; t++) {
        s[t].lo = SIZE_MAX;
        for (int m = 0; m < 2; m++)
            ok &= (s[t].values[m] = malloc(nodes * sizeof(float))) != NULL;
        for (int m = 0; ok && m < 5; m++)
            ok &= (s[t].map[m] = malloc(nodes * sizeof(uint32_t))) != NULL;
    }
    if (!ok) {
        free_scratch(s, workers);
        return NULL;
    }
    return s;
}

static void reset_scratch(scratch *s, int workers)
{
    for (int t = 0; t < workers; t++)
        s[t].lo = SIZE_MAX;
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
}

/* Both passes; *out filled on 0. */
static int run(job *w, int threads, sdf_surface *out, sdf_diag *diag)
{
    size_t n2 = w->g.n[2];
    size_t chunk = n2 / (8 * (size_t)sdf__effective_threads(threads, n2, 1));
    chunk = chunk ? chunk : 1;
    int workers = sdf__effective_threads(threads, n2, chunk);
    w->scratch = alloc_scratch(&w->g, workers);
    w->count = calloc(n2, sizeof *w->count);
    w->first = calloc(n2 + 1, sizeof *w->first);
    w->layers = calloc(n2, sizeof *w->layers);
    int rc = w->scratch && w->count && w->first && w->layers ? 0 : SDF_ENOMEM;
    if (!rc) {
        sdf__parallel_for(n2, chunk, workers, count_layers, w);
        for (size_t k = 0; k < n2; k++)
            w->first[k + 1] = w->first[k] + w->count[k];
        if (w->first[n2] >= MAX_VERTICES)
            rc = SDF_ELIMIT;
    }
    if (!rc && !(w->vertices = malloc((size_t)w->first[n2] * 3 * sizeof(float) + 1)))
        rc = SDF_ENOMEM;
    if (!rc) {
        reset_scratch(w->scratch, workers);
        sdf__parallel_for(n2 - 1, chunk, workers, cell_layers, w);
        rc = w->failed ? SDF_ENOMEM : join(w, n2 - 1, w->first[n2], out);
    }
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
    job w = {.g = {.v = volume, .iso = opts->iso, .pad = opts->cap != 0}};
    for (int a = 0; a < 3; a++)
        w.g.n[a] = volume->info.dims[a] + 2 * (size_t)w.g.pad;
    sdf_surface *s = calloc(1, sizeof *s);
    if (!s)
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of memory");
    int rc = run(&w, opts->threads, s, diag);
    if (rc) {
        free(s);
        return rc;
    }
    *out = s;
    return 0;
}

const float *sdf_surface_vertices(const sdf_surface *surface, size_t *count)
{
    *count = surface->vertex_count;
    return surface->vertices;
}

const uint32_t *sdf_surface_triangles(const sdf_surface *surface, size_t *count)
{
    *count = surface->triangle_count;
    return surface->triangles;
}

int sdf_surface_to_mesh(const sdf_surface *surface, const sdf_mesh_options *opts,
                        sdf_mesh **out, sdf_diag *diag)
{
    return sdf_mesh_create(surface->vertices, surface->vertex_count, surface->triangles,
                           surface->triangle_count, opts, out, diag);
}

void sdf_surface_destroy(sdf_surface *surface)
{
    if (!surface)
        return;
    free(surface->vertices);
    free(surface->triangles);
    free(surface);
}
