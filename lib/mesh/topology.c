/* topology.c - welding and edge analysis (see topology.h). */
#include "mesh/topology.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/parallel.h"

static size_t table_size(size_t n)
{
    size_t cap = 16;
    while (cap < 2 * n)
        cap *= 2;
    return cap;
}

static uint64_t mix(uint64_t k)
{
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ULL;
    return k ^ (k >> 33);
}

/* ---- welding --------------------------------------------------------------------------- */

static void position_bits(const float *p, uint32_t out[3])
{
    for (int i = 0; i < 3; i++) {
        float f = p[i] == 0.0f ? 0.0f : p[i]; /* -0 == +0 */
        memcpy(&out[i], &f, 4);
    }
}

#define WELD_AHEAD 16 /* vertices between a slot's prefetch and its use */

static size_t weld_hash(const uint32_t key[3])
{
    return (size_t)mix((uint64_t)key[0] * 73856093u ^ (uint64_t)key[1] << 21 ^
                       (uint64_t)key[2] << 42 ^ key[2]);
}

typedef struct remap_job {
    uint32_t *triangles;
    const uint32_t *remap;
} remap_job;

static void remap_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const remap_job *job = ctx;
    for (size_t i = begin; i < end; i++)
        job->triangles[i] = job->remap[job->triangles[i]];
}

int sdf__weld(const float *positions, size_t vertex_count, uint32_t *triangles,
              size_t triangle_count, float **out, size_t *out_count)
{
    size_t cap = table_size(vertex_count);
    uint32_t *slot = malloc(cap * sizeof *slot);
    uint32_t *remap = malloc((vertex_count ? vertex_count : 1) * sizeof *remap);
    float *welded = malloc((3 * vertex_count + 1) * sizeof *welded);
    if (!slot || !remap || !welded) {
        free(slot);
        free(remap);
        free(welded);
        return SDF_ENOMEM;
    }
    memset(slot, 0xff, cap * sizeof *slot);
    size_t n = 0;
    for (size_t v = 0; v < vertex_count; v++) {
        uint32_t key[3];
        if (v + WELD_AHEAD < vertex_count) { /* large meshes' tables outgrow the caches */
            position_bits(positions + 3 * (v + WELD_AHEAD), key);
            __builtin_prefetch(&slot[weld_hash(key) & (cap - 1)]);
        }
        position_bits(positions + 3 * v, key);
        size_t h = weld_hash(key) & (cap - 1);
        for (;; h = (h + 1) & (cap - 1)) {
            if (slot[h] == UINT32_MAX) {
                slot[h] = (uint32_t)n;
                memcpy(welded + 3 * n, positions + 3 * v, 3 * sizeof(float));
                remap[v] = (uint32_t)n++;
                break;
            }
            uint32_t other[3];
            position_bits(welded + 3 * slot[h], other);
            if (!memcmp(key, other, sizeof key)) {
                remap[v] = slot[h];
                break;
            }
        }
    }
    remap_job job = {triangles, remap};
    sdf__parallel_for(3 * triangle_count, (size_t)1 << 16, 0, remap_range, &job);
    welded[3 * n] = 0.0f; /* padding Embree may read */
    free(slot);
    free(remap);
    *out = welded;
    *out_count = n;
    return 0;
}

/* ---- edges ----------------------------------------------------------------------------- */

static int has_repeated_corner(const uint32_t *t)
{
    return t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
}

static double triangle_area2(const float *pos, const uint32_t *t)
{
    const float *a = pos + 3 * t[0], *b = pos + 3 * t[1], *c = pos + 3 * t[2];
    double u[3], v[3];
    for (int i = 0; i < 3; i++) {
        u[i] = (double)b[i] - a[i];
        v[i] = (double)c[i] - a[i];
    }
    double x = u[1] * v[2] - u[2] * v[1], y = u[2] * v[0] - u[0] * v[2],
           z = u[0] * v[1] - u[1] * v[0];
    return x * x + y * y + z * z;
}

/* Signed volume of the tetrahedron (origin, a, b, c); their sum is the enclosed volume. */
static double signed_volume(const float *pos, const uint32_t *t)
{
    const float *a = pos + 3 * t[0], *b = pos + 3 * t[1], *c = pos + 3 * t[2];
    double cx = (double)b[1] * c[2] - (double)b[2] * c[1];
    double cy = (double)b[2] * c[0] - (double)b[0] * c[2];
    double cz = (double)b[0] * c[1] - (double)b[1] * c[0];
    return (a[0] * cx + a[1] * cy + a[2] * cz) / 6.0;
}

/* Triangles per partial sum of the summary: a fixed split, so that the volume's rounding
 * does not depend on the number of threads. */
#define SUMMARY_CHUNK 65536

typedef struct summary_part {
    double lo[3], hi[3], volume;
    size_t degenerate;
} summary_part;

typedef struct summary_job {
    const float *pos;
    const uint32_t *tris;
    summary_part *parts; /* one per SUMMARY_CHUNK triangles */
} summary_job;

static void summary_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const summary_job *job = ctx;
    summary_part p = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, 0, 0};
    for (size_t t = begin; t < end; t++) {
        const uint32_t *tri = job->tris + 3 * t;
        for (int k = 0; k < 3; k++) {
            for (int i = 0; i < 3; i++) {
                double x = job->pos[3 * tri[k] + i];
                p.lo[i] = x < p.lo[i] ? x : p.lo[i];
                p.hi[i] = x > p.hi[i] ? x : p.hi[i];
            }
        }
        if (has_repeated_corner(tri) || triangle_area2(job->pos, tri) == 0.0)
            p.degenerate++;
        p.volume += signed_volume(job->pos, tri);
    }
    job->parts[begin / SUMMARY_CHUNK] = p;
}

/* Box, diagonal, volume and degenerate triangles, over chunks of triangles on all CPUs. */
static int geometry_summary(const float *pos, const uint32_t *tris, size_t nt,
                            sdf_mesh_report *r)
{
    size_t chunks = (nt + SUMMARY_CHUNK - 1) / SUMMARY_CHUNK;
    summary_job job = {pos, tris, malloc((chunks + 1) * sizeof *job.parts)};
    if (!job.parts)
        return SDF_ENOMEM;
    sdf__parallel_for(nt, SUMMARY_CHUNK, 0, summary_range, &job);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double volume = 0;
    size_t degenerate = 0;
    for (size_t c = 0; c < chunks; c++) {
        const summary_part *p = &job.parts[c];
        for (int i = 0; i < 3; i++) {
            lo[i] = p->lo[i] < lo[i] ? p->lo[i] : lo[i];
            hi[i] = p->hi[i] > hi[i] ? p->hi[i] : hi[i];
        }
        volume += p->volume;
        degenerate += p->degenerate;
    }
    free(job.parts);
    double d2 = 0;
    for (int i = 0; i < 3; i++) {
        r->bbox_min[i] = (float)lo[i];
        r->bbox_max[i] = (float)hi[i];
        d2 += (hi[i] - lo[i]) * (hi[i] - lo[i]);
    }
    r->diagonal = sqrt(d2);
    r->volume = volume;
    r->degenerate_triangles = degenerate;
    return 0;
}

/* A half-edge filed under its lower vertex: the other vertex, and which triangle corner
 * (3 t + k) it leaves from. */
typedef struct half_edge {
    uint32_t other, corner;
} half_edge;

static int by_other(const void *a, const void *b)
{
    const half_edge *x = a, *y = b;
    return x->other < y->other ? -1 : x->other > y->other ? 1 : (x->corner > y->corner) - (x->corner < y->corner);
}

/* Sort a vertex's few half-edges: insertion sort for the usual handful, qsort for a fan. */
static void sort_half_edges(half_edge *h, size_t n)
{
    if (n > 32) {
        qsort(h, n, sizeof *h, by_other);
        return;
    }
    for (size_t i = 1; i < n; i++) {
        half_edge x = h[i];
        size_t j = i;
        while (j > 0 && by_other(&h[j - 1], &x) > 0) {
            h[j] = h[j - 1];
            j--;
        }
        h[j] = x;
    }
}

#define GROUP_CHUNK 16384 /* vertices per task of the grouping into edges */

/* One chunk of vertices' edges: how many (then, numbering, the first one's id) and their
 * kinds. */
typedef struct group_chunk {
    size_t edges, boundary, nonmanifold, misoriented;
} group_chunk;

typedef struct group_job {
    const uint32_t *triangles;
    half_edge *filed;
    const size_t *start; /* vertex v's half-edges are filed[start[v] .. start[v + 1]) */
    uint32_t *edge_of;
    sdf__edge_faces *faces; /* or NULL */
    group_chunk *chunk;
    int number; /* 0: sort and count the edges; 1: number them */
} group_job;

static void group_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const group_job *job = ctx;
    group_chunk *c = &job->chunk[begin / GROUP_CHUNK];
    size_t edge = c->edges;
    for (size_t v = begin; v < end; v++) {
        half_edge *h = job->filed + job->start[v];
        size_t n = job->start[v + 1] - job->start[v];
        if (!job->number) {
            sort_half_edges(h, n);
            for (size_t i = 0; i < n; i++)
                c->edges += i == 0 || h[i].other != h[i - 1].other;
            continue;
        }
        for (size_t i = 0; i < n;) {
            size_t j = i;
            int balance = 0; /* +1 per use leaving the lower vertex, -1 per use entering it */
            if (job->faces) /* the uses of this edge are filed[start[v] + i .. start[v] + j) */
                job->faces->start[edge] = job->start[v] + i;
            for (; j < n && h[j].other == h[i].other; j++) {
                job->edge_of[h[j].corner] = (uint32_t)edge;
                balance += job->triangles[h[j].corner] == v ? 1 : -1;
                if (job->faces)
                    job->faces->face[job->start[v] + j] = h[j].corner / 3;
            }
            size_t uses = j - i;
            c->boundary += uses == 1;
            c->nonmanifold += uses > 2;
            c->misoriented += uses == 2 && balance != 0;
            edge++;
            i = j;
        }
    }
}

void sdf__edge_faces_free(sdf__edge_faces *faces)
{
    free(faces->start);
    free(faces->face);
    faces->start = NULL;
    faces->face = NULL;
}

/* File every half-edge of a triangle without a repeated corner under its lower vertex, by a
 * counting sort: afterwards start[v] is vertex v's first slot in `filed` and start[v + 1] its
 * end (start: vertex_count + 2 zeros on entry). Every edge_of becomes SDF__NO_EDGE. */
static void file_half_edges(const uint32_t *triangles, size_t triangle_count,
                            size_t vertex_count, size_t *start, half_edge *filed,
                            uint32_t *edge_of)
{
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *tri = triangles + 3 * t;
        for (int k = 0; k < 3; k++) {
            edge_of[3 * t + k] = SDF__NO_EDGE;
            if (!has_repeated_corner(tri)) {
                uint32_t a = tri[k], b = tri[(k + 1) % 3];
                start[(a < b ? a : b) + 2]++;
            }
        }
    }
    for (size_t v = 2; v < vertex_count + 2; v++) /* start[v + 1] = first slot of vertex v */
        start[v] += start[v - 1];
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *tri = triangles + 3 * t;
        if (has_repeated_corner(tri))
            continue;
        for (int k = 0; k < 3; k++) {
            uint32_t a = tri[k], b = tri[(k + 1) % 3];
            filed[start[(a < b ? a : b) + 1]++] = (half_edge){a < b ? b : a, (uint32_t)(3 * t + k)};
        }
    }
    assert(vertex_count == 0 || start[vertex_count] <= 3 * triangle_count);
}

/* Group each vertex's half-edges into edges on all CPUs: chunks of vertices count theirs,
 * then number them from the count before the chunk, so ids are the same on any number of
 * threads. Returns the edge count; the counts of boundary, non-manifold and misoriented
 * edges go to r. */
static size_t number_edges(group_job *job, size_t chunks, size_t vertex_count,
                           sdf_mesh_report *r)
{
    sdf__parallel_for(vertex_count, GROUP_CHUNK, 0, group_range, job);
    size_t edges = 0, boundary = 0, nonmanifold = 0, misoriented = 0;
    for (size_t c = 0; c < chunks; c++) {
        size_t here = job->chunk[c].edges;
        job->chunk[c].edges = edges; /* now its first edge id */
        edges += here;
    }
    job->number = 1;
    sdf__parallel_for(vertex_count, GROUP_CHUNK, 0, group_range, job);
    for (size_t c = 0; c < chunks; c++) {
        boundary += job->chunk[c].boundary;
        nonmanifold += job->chunk[c].nonmanifold;
        misoriented += job->chunk[c].misoriented;
    }
    r->boundary_edges = boundary;
    r->nonmanifold_edges = nonmanifold;
    r->misoriented_edges = misoriented;
    r->edge_manifold = nonmanifold == 0;
    r->closed = boundary == 0 && nonmanifold == 0 && misoriented == 0 && edges > 0;
    return edges;
}

/* Edges are found by filing every half-edge under its lower vertex (a counting sort, so
 * memory is read in order, where a hash table's probes miss the cache on large meshes) and
 * grouping each vertex's list by the other vertex. Edge ids follow (lower vertex, upper vertex)
 * order. */
int sdf__analyse(const float *positions, const uint32_t *triangles, size_t triangle_count,
                 uint32_t **edge_of_out, size_t *edge_count, sdf__edge_faces *faces,
                 sdf_mesh_report *r)
{
    size_t vertex_count = 0;
    for (size_t i = 0; i < 3 * triangle_count; i++)
        vertex_count = triangles[i] >= vertex_count ? (size_t)triangles[i] + 1 : vertex_count;
    size_t chunks = (vertex_count + GROUP_CHUNK - 1) / GROUP_CHUNK;
    size_t *start = calloc(vertex_count + 2, sizeof *start);
    half_edge *filed = malloc((3 * triangle_count + 1) * sizeof *filed);
    uint32_t *edge_of = malloc((3 * triangle_count + 1) * sizeof *edge_of);
    group_chunk *chunk = calloc(chunks + 1, sizeof *chunk);
    /* At most one edge per half-edge; trimmed once the edges are counted. */
    sdf__edge_faces found = {0};
    if (faces) {
        found.start = malloc((3 * triangle_count + 1) * sizeof *found.start);
        found.face = malloc((3 * triangle_count + 1) * sizeof *found.face);
    }
    if (!start || !filed || !edge_of || !chunk || (faces && (!found.start || !found.face))) {
        free(start);
        free(filed);
        free(edge_of);
        free(chunk);
        sdf__edge_faces_free(&found);
        return SDF_ENOMEM;
    }
    file_half_edges(triangles, triangle_count, vertex_count, start, filed, edge_of);
    group_job job = {triangles, filed, start, edge_of, faces ? &found : NULL, chunk, 0};
    size_t edges = number_edges(&job, chunks, vertex_count, r);
    free(job.chunk);
    if (faces) {
        found.start[edges] = start[vertex_count];
        size_t *trimmed = realloc(found.start, ((size_t)edges + 1) * sizeof *found.start);
        found.start = trimmed ? trimmed : found.start;
        *faces = found;
    }
    free(start);
    free(filed);
    if (geometry_summary(positions, triangles, triangle_count, r)) {
        free(edge_of);
        if (faces)
            sdf__edge_faces_free(faces);
        return SDF_ENOMEM;
    }
    *edge_of_out = edge_of;
    *edge_count = edges;
    return 0;
}

void sdf__flip(uint32_t *triangles, uint32_t *edge_of, size_t triangle_count)
{
    /* Corners (0,1,2) become (0,2,1): edge 0 (0->1) is now edge 2 (1->0) reversed, edge 2
     * (2->0) is now edge 0, edge 1 (1->2) stays edge 1. */
    for (size_t t = 0; t < triangle_count; t++) {
        uint32_t *tri = triangles + 3 * t, *e = edge_of + 3 * t, tmp;
        tmp = tri[1], tri[1] = tri[2], tri[2] = tmp;
        tmp = e[0], e[0] = e[2], e[2] = tmp;
    }
}
