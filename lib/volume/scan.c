/* scan.c - closest-feature scan conversion of a volume's lattice (see scan.h).
 *
 * Features are numbered faces first, then edges (the mesh's edge ids), then vertices. Each
 * feature's region is built as a convex polyhedron twice over: as half-spaces n . p <= c,
 * which decide which nodes of a lattice row it holds, and as corners and edges, whose
 * crossings with a slice give the range of rows to visit. Regions reach only as far as any
 * node can be from the surface (`reach_front` on the outward side, `reach_back` inside),
 * which a coarse lattice of exact queries bounds. Worker threads take runs of features in
 * Morton order, each into its own per-node "best so far" arrays (no locks); the rows are
 * then finished in parallel, the workers' bests merged by (distance, feature id) so the
 * result does not depend on how the features were shared out. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "bvh/embree.h"
#include "core/parallel.h"
#include "mesh/mesh.h"
#include "mesh/topology.h"
#include "query/filter.h"
#include "query/packet.h"
#include "query/triangle.h"
#include "volume/scan.h"

#define MAX_PLANES 64      /* a vertex with more edges keeps 62 of its planes: a larger region */
#define MAX_CORNERS 65
#define MAX_EDGES 128
#define COARSE_STEP 8      /* nodes between the coarse lattice's nodes */
#define FEATURE_CHUNK 256  /* features per work item */
#define SCAN_BUDGET_BYTES ((size_t)64 << 20) /* the workers' per-node arrays of one call */

enum { FACE, EDGE, VERTEX };

/* Corners 0-2 and 3-5 of a triangular prism are its two ends, i and i + 3 joined. */
static const uint8_t prism_edges[9][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5},
                                          {5, 3}, {0, 3}, {1, 4}, {2, 5}};

typedef struct region {
    int kind;
    double origin[3], dir[3]; /* face: a corner, unit normal; edge: an end, unit direction;
                                 vertex: its position */
    int planes;
    double plane[MAX_PLANES][4];
    int corners;
    double corner[MAX_CORNERS][3];
    int edges;
    uint8_t edge[MAX_EDGES][2];
} region;

struct sdf__scan {
    const sdf_mesh *mesh;
    sdf_query_options query;
    size_t dims[3];
    double origin[3], spacing[3];
    double *coord[3];          /* node coordinates per axis, as the float points sdf_query gets */
    double *pos;               /* vertex positions in double, 3 per vertex */
    size_t faces, edges, vertices, features;
    uint32_t *edge_end;        /* 2 per edge */
    uint32_t *edge_first, *edge_tri;     /* triangles of each edge (CSR) */
    uint32_t *vert_first, *vert_nbr;     /* neighbour vertices of each vertex (CSR) */
    uint32_t *vtri_first, *vtri;         /* triangles of each vertex (CSR) */
    uint32_t *order;           /* features in Morton order of their positions: neighbours in
                                  this order write to nearby nodes, so the per-node arrays stay
                                  in cache */
    double reach_front, reach_back;
    double slack;              /* rounding slack of every half-space, world units */
    double row_pad;            /* padding of a slice's row range, world units */
    double inv_spacing[3];
    double index_slack[3];     /* float rounding of node coordinates, in nodes */
    double scale2;             /* squared size of the scene: the floor of the exactness check */
};

/* ---- small vector helpers ---------------------------------------------------------------- */

static inline double min2(double a, double b) { return a < b ? a : b; }
static inline double max2(double a, double b) { return a > b ? a : b; }

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(double out[3], const double a[3], const double b[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static double normalize3(double v[3])
{
    double len = sqrt(dot3(v, v));
    if (len > 0)
        for (int a = 0; a < 3; a++)
            v[a] /= len;
    return len;
}

static void add_plane(const sdf__scan *s, region *r, const double n[3], double c)
{
    if (r->planes == MAX_PLANES)
        return; /* fewer planes: a larger region, still holding every node it must */
    double *p = r->plane[r->planes++];
    p[0] = n[0], p[1] = n[1], p[2] = n[2], p[3] = c + s->slack;
}

/* The plane n . (p - at) <= offset. */
static void add_plane_at(const sdf__scan *s, region *r, const double n[3], const double at[3],
                         double offset)
{
    add_plane(s, r, n, dot3(n, at) + offset);
}

static const double *vertex(const sdf__scan *s, uint32_t v)
{
    return s->pos + 3 * (size_t)v;
}

/* Corners at + t m + w q + e d for the given ranges: an oriented box, with its 12 edges. */
static void box_corners(region *r, const double at[3], const double m[3], const double t[2],
                        const double q[3], double w, const double d[3], const double e[2])
{
    r->corners = 8;
    for (int c = 0; c < 8; c++) {
        double tc = t[c & 1], wc = c & 2 ? w : -w, ec = e[c >> 2];
        for (int a = 0; a < 3; a++)
            r->corner[c][a] = at[a] + tc * m[a] + wc * q[a] + ec * d[a];
    }
    r->edges = 0;
    for (int c = 0; c < 8; c++)
        for (int bit = 1; bit < 8; bit <<= 1)
            if (!(c & bit)) {
                r->edge[r->edges][0] = (uint8_t)c;
                r->edge[r->edges][1] = (uint8_t)(c | bit);
                r->edges++;
            }
}

/* ---- regions ----------------------------------------------------------------------------- */

/* The prism over face t: points whose foot on the face's plane lies inside the face. */
static int face_region(const sdf__scan *s, size_t t, region *r)
{
    const uint32_t *tri = s->mesh->triangles + 3 * t;
    const double *v[3] = {vertex(s, tri[0]), vertex(s, tri[1]), vertex(s, tri[2])};
    double n[3];
    sdf__triangle_normal(v[0], v[1], v[2], n);
    if (normalize3(n) == 0)
        return 0; /* no area: its points are its edges' */
    r->kind = FACE;
    memcpy(r->origin, v[0], sizeof r->origin);
    memcpy(r->dir, n, sizeof r->dir);
    r->planes = 0;
    for (int q = 0; q < 3; q++) {
        double e[3], m[3];
        for (int a = 0; a < 3; a++)
            e[a] = v[(q + 1) % 3][a] - v[q][a];
        cross3(m, e, n); /* outward in the face's plane */
        if (normalize3(m) > 0)
            add_plane_at(s, r, m, v[q], 0);
    }
    double front = s->reach_front, back = s->reach_back, minus_n[3] = {-n[0], -n[1], -n[2]};
    add_plane_at(s, r, n, v[0], front);
    add_plane_at(s, r, minus_n, v[0], back);
    r->corners = 6;
    for (int q = 0; q < 3; q++)
        for (int a = 0; a < 3; a++) {
            r->corner[q][a] = v[q][a] + front * n[a];
            r->corner[q + 3][a] = v[q][a] - back * n[a];
        }
    r->edges = 9;
    memcpy(r->edge, prism_edges, sizeof prism_edges);
    return 1;
}

/* The wedge beside edge e: points whose foot on the edge's line lies on the edge and which
 * lie on no incident face's side of the edge. Its cross-section, a sector of the reach's
 * radius, is bounded by a triangle (narrow sectors) or a rectangle. */
static int edge_region(const sdf__scan *s, size_t e, region *r)
{
    const double *a = vertex(s, s->edge_end[2 * e]), *b = vertex(s, s->edge_end[2 * e + 1]);
    double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double len = normalize3(d);
    if (len == 0)
        return 0;
    r->kind = EDGE;
    memcpy(r->origin, a, sizeof r->origin);
    memcpy(r->dir, d, sizeof r->dir);
    r->planes = 0;
    double minus_d[3] = {-d[0], -d[1], -d[2]};
    add_plane_at(s, r, minus_d, a, 0);
    add_plane_at(s, r, d, b, 0);
    double u[2][3], normals[2][3];
    int valid = 0;
    for (uint32_t k = s->edge_first[e]; k < s->edge_first[e + 1]; k++) {
        const uint32_t *tri = s->mesh->triangles + 3 * (size_t)s->edge_tri[k];
        uint32_t c = tri[0];
        for (int q = 1; q < 3; q++)
            if (c == s->edge_end[2 * e] || c == s->edge_end[2 * e + 1])
                c = tri[q];
        double w[3], uf[3];
        for (int x = 0; x < 3; x++)
            w[x] = vertex(s, c)[x] - a[x];
        double along = dot3(w, d);
        for (int x = 0; x < 3; x++)
            uf[x] = w[x] - along * d[x];
        if (normalize3(uf) == 0)
            continue; /* a zero-area face does not bound the edge's region */
        add_plane_at(s, r, uf, a, 0);
        if (valid < 2) {
            memcpy(u[valid], uf, sizeof uf);
            const double *v3[3] = {vertex(s, tri[0]), vertex(s, tri[1]), vertex(s, tri[2])};
            sdf__triangle_normal(v3[0], v3[1], v3[2], normals[valid]);
            normalize3(normals[valid]);
        }
        valid++;
    }
    /* Cross-section: t in [t0, t1] along m, |w| <= half_width along q = d x m. */
    double reach = max2(s->reach_front, s->reach_back), m[3], t[2], half_width;
    if (valid == 2) { /* a closed mesh's edge has two faces */
        double sum[3] = {u[0][0] + u[1][0], u[0][1] + u[1][1], u[0][2] + u[1][2]};
        double spread = sqrt(dot3(sum, sum)); /* 2 cos(beta / 2), beta between u0 and u1 */
        if (spread >= 1e-6) {                 /* a sector of angle pi - beta around -sum */
            for (int x = 0; x < 3; x++)
                m[x] = -sum[x] / spread;
            double side = dot3(m, normals[0]) + dot3(m, normals[1]);
            reach = side > 0 ? s->reach_front : s->reach_back;
            t[0] = 0, t[1] = reach;
            half_width = reach * min2(1.0, 0.5 * spread);
        } else { /* flat: the plane of the normals, both sides */
            memcpy(m, normals[0], sizeof m);
            t[0] = -s->reach_back, t[1] = s->reach_front;
            half_width = reach * spread;
        }
    } else { /* a face without area beside it: a cylinder around the edge */
        double any[3] = {1, 0, 0};
        if (fabs(d[0]) > 0.9)
            any[0] = 0, any[1] = 1;
        cross3(m, d, any);
        normalize3(m);
        t[0] = -reach, t[1] = reach, half_width = reach;
    }
    double q[3], minus_m[3] = {-m[0], -m[1], -m[2]}, minus_q[3];
    cross3(q, d, m);
    for (int x = 0; x < 3; x++)
        minus_q[x] = -q[x];
    add_plane_at(s, r, m, a, t[1]);
    if (t[0] == 0 && half_width <= 0.866 * t[1]) {
        /* A sector of half-angle gamma <= 60 degrees: inside the triangle (0, 0),
         * (reach, +-reach tan gamma) of the (m, q) plane, its sides the faces' planes. */
        double sin_g = half_width / t[1], spread_w = t[1] * sin_g / sqrt(1 - sin_g * sin_g);
        r->corners = 6;
        for (int end = 0; end < 2; end++)
            for (int x = 0; x < 3; x++) {
                double at = a[x] + (end ? len : 0) * d[x];
                r->corner[3 * end][x] = at;
                r->corner[3 * end + 1][x] = at + t[1] * m[x] - spread_w * q[x];
                r->corner[3 * end + 2][x] = at + t[1] * m[x] + spread_w * q[x];
            }
        r->edges = 9;
        memcpy(r->edge, prism_edges, sizeof prism_edges);
        return 1;
    }
    add_plane_at(s, r, minus_m, a, -t[0]);
    add_plane_at(s, r, q, a, half_width);
    add_plane_at(s, r, minus_q, a, half_width);
    double ends[2] = {0, len};
    box_corners(r, a, m, t, q, half_width, d, ends);
    return 1;
}

/* The cone at vertex v: directions x with x . (w - v) <= 0 for every neighbour w. Its
 * generators are the planes' pairwise intersections that satisfy every plane; the region is
 * the pyramid they span, capped at the reach along its axis. */
static int vertex_region(const sdf__scan *s, size_t v, region *r)
{
    const double *p = vertex(s, (uint32_t)v);
    uint32_t first = s->vert_first[v], count = s->vert_first[v + 1] - first;
    if (count == 0)
        return 0;
    r->kind = VERTEX;
    memcpy(r->origin, p, sizeof r->origin);
    r->planes = 0;
    double e[MAX_PLANES][3];
    int n = 0;
    for (uint32_t k = 0; k < count && n < MAX_PLANES - 2; k++) {
        const double *w = vertex(s, s->vert_nbr[first + k]);
        double dir[3] = {w[0] - p[0], w[1] - p[1], w[2] - p[2]};
        if (normalize3(dir) == 0)
            continue;
        memcpy(e[n], dir, sizeof dir);
        add_plane_at(s, r, dir, p, 0);
        n++;
    }
    double gen[MAX_CORNERS - 1][3], axis[3] = {0, 0, 0};
    int g = 0, pointed = 1;
    for (int i = 0; i < n && pointed; i++)
        for (int j = i + 1; j < n && pointed; j++) {
            double ray[3];
            cross3(ray, e[i], e[j]);
            if (normalize3(ray) < 1e-9)
                continue;
            for (int sign = -1; sign <= 1; sign += 2) {
                double cand[3] = {sign * ray[0], sign * ray[1], sign * ray[2]};
                int ok = 1;
                for (int l = 0; l < n && ok; l++)
                    ok = dot3(cand, e[l]) <= 1e-9;
                for (int h = 0; h < g && ok; h++)
                    ok = dot3(cand, gen[h]) < 1 - 1e-12; /* a repeat */
                if (!ok)
                    continue;
                if (g == MAX_CORNERS - 1) {
                    pointed = 0;
                    break;
                }
                memcpy(gen[g++], cand, sizeof cand);
            }
        }
    if (g == 0 && pointed)
        return 0; /* the cone is the vertex itself (or a line its faces' regions border) */
    for (int h = 0; h < g; h++)
        for (int a = 0; a < 3; a++)
            axis[a] += gen[h][a];
    pointed = pointed && normalize3(axis) > 1e-9;
    for (int h = 0; h < g && pointed; h++)
        pointed = dot3(gen[h], axis) >= 0.05;
    double reach = max2(s->reach_front, s->reach_back);
    if (!pointed) { /* a cone containing a line, or too wide: a cube of the reach */
        double x[3] = {1, 0, 0}, y[3] = {0, 1, 0}, z[3] = {0, 0, 1}, span[2] = {-reach, reach};
        box_corners(r, p, x, span, y, reach, z, span);
        return 1;
    }
    /* The side the cone opens to: the mean of its faces' normals. */
    double side = 0;
    for (uint32_t k = s->vtri_first[v]; k < s->vtri_first[v + 1]; k++) {
        const uint32_t *tri = s->mesh->triangles + 3 * (size_t)s->vtri[k];
        double nf[3];
        sdf__triangle_normal(vertex(s, tri[0]), vertex(s, tri[1]), vertex(s, tri[2]), nf);
        normalize3(nf);
        side += dot3(nf, axis);
    }
    reach = side > 0 ? s->reach_front : s->reach_back;
    add_plane_at(s, r, axis, p, reach);
    /* Order the generators around the axis, so the base polygon's edges are neighbours. */
    double b1[3], b2[3], any[3] = {1, 0, 0}, angle[MAX_CORNERS - 1];
    if (fabs(axis[0]) > 0.9)
        any[0] = 0, any[1] = 1;
    cross3(b1, axis, any);
    normalize3(b1);
    cross3(b2, axis, b1);
    for (int h = 0; h < g; h++)
        angle[h] = atan2(dot3(gen[h], b2), dot3(gen[h], b1));
    for (int h = 1; h < g; h++) /* insertion sort: a handful of generators */
        for (int k = h; k > 0 && angle[k - 1] > angle[k]; k--) {
            double ta = angle[k], tg[3];
            angle[k] = angle[k - 1], angle[k - 1] = ta;
            memcpy(tg, gen[k], sizeof tg);
            memcpy(gen[k], gen[k - 1], sizeof tg);
            memcpy(gen[k - 1], tg, sizeof tg);
        }
    r->corners = g + 1;
    memcpy(r->corner[0], p, sizeof r->corner[0]);
    r->edges = 0;
    for (int h = 0; h < g; h++) {
        double len = reach / dot3(gen[h], axis);
        for (int a = 0; a < 3; a++)
            r->corner[h + 1][a] = p[a] + len * gen[h][a];
        r->edge[r->edges][0] = 0, r->edge[r->edges][1] = (uint8_t)(h + 1), r->edges++;
        if (g > 1) {
            r->edge[r->edges][0] = (uint8_t)(h + 1);
            r->edge[r->edges][1] = (uint8_t)((h + 1) % g + 1);
            r->edges++;
        }
    }
    return 1;
}

static int build_region(const sdf__scan *s, size_t f, region *r)
{
    int ok = f < s->faces             ? face_region(s, f, r)
             : f < s->faces + s->edges ? edge_region(s, f - s->faces, r)
                                       : vertex_region(s, f - s->faces - s->edges, r);
    return ok;
}

/* ---- scanning ---------------------------------------------------------------------------- */

typedef struct call_state {
    sdf__scan *scan;
    size_t k0, k1;     /* the call's slices */
    size_t nodes;      /* in the call */
    double *best;      /* per worker and node: smallest squared distance so far */
    uint32_t *winner;  /* its feature (ties: the lowest id, so the merge is deterministic) */
    region *regions;   /* per worker: the region being scanned */
    float *points;     /* per worker: a row of nodes */
    sdf__hit *hits;    /* per worker: their closest points */
    int workers;
    float *out;
} call_state;

/* Node index range [lo, hi] of coordinates [from, to] on axis a, widened by the float
 * rounding of the node coordinates (callers compare a node's own coordinate); 0 when empty. */
static int node_range(const sdf__scan *s, int a, double from, double to, size_t first,
                      size_t last, size_t *lo, size_t *hi)
{
    double l = ceil((from - s->origin[a]) * s->inv_spacing[a] - s->index_slack[a]);
    double h = floor((to - s->origin[a]) * s->inv_spacing[a] + s->index_slack[a]);
    if (!(l <= h) || h < (double)first || l > (double)last)
        return 0;
    *lo = l < (double)first ? first : (size_t)l;
    *hi = h > (double)last ? last : (size_t)h;
    return 1;
}

/* A slice's cross-section fits this many lattice points or fewer: test each one against the
 * planes instead of computing row intervals (thin prisms cross a slice in a point or two). */
#define FEW_POINTS 12

/* Hand the region's feature to every node of the call it holds. Slices run across the
 * region's thinnest axis A, rows across the middle one B, and each row along its longest C. */
static void scan_region(const call_state *st, const region *r, uint32_t feature, double *best,
                        uint32_t *winner)
{
    const sdf__scan *s = st->scan;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int c = 0; c < r->corners; c++)
        for (int a = 0; a < 3; a++)
            lo[a] = min2(lo[a], r->corner[c][a]), hi[a] = max2(hi[a], r->corner[c][a]);
    size_t first[3] = {0, 0, st->k0}, last[3] = {s->dims[0] - 1, s->dims[1] - 1, st->k1 - 1};
    size_t from[3], to[3];
    for (int a = 0; a < 3; a++)
        if (!node_range(s, a, lo[a] - s->row_pad, hi[a] + s->row_pad, first[a], last[a],
                        &from[a], &to[a]))
            return;
    int A = 0, C = 0;
    for (int a = 1; a < 3; a++) {
        if (to[a] - from[a] < to[A] - from[A])
            A = a;
        if (to[a] - from[a] >= to[C] - from[C])
            C = a;
    }
    if (A == C)
        C = (A + 1) % 3;
    int B = 3 - A - C;
    /* Planes by the sign of their C component: upper bounds on C, lower bounds, neither;
     * each as (n_A, n_B, n_C, 1 / n_C, c). */
    double pl_sorted[MAX_PLANES][5], off[MAX_PLANES];
    int n_up = 0, n_down = 0, n_flat = 0;
    for (int pass = 0; pass < 3; pass++)
        for (int p = 0; p < r->planes; p++) {
            const double *pl = r->plane[p];
            int kind = pl[C] > 1e-12 ? 0 : pl[C] < -1e-12 ? 1 : 2;
            if (kind != pass)
                continue;
            double *o5 = pl_sorted[n_up + n_down + n_flat];
            o5[0] = pl[A], o5[1] = pl[B], o5[2] = pl[C], o5[3] = kind < 2 ? 1 / pl[C] : 0;
            o5[4] = pl[3];
            *(kind == 0 ? &n_up : kind == 1 ? &n_down : &n_flat) += 1;
        }
    const double (*up)[5] = pl_sorted, (*down)[5] = pl_sorted + n_up;
    const double (*flat)[5] = pl_sorted + n_up + n_down;
    /* The region's edges as lines over A: B and C at A = 0 and their slopes (edges lying
     * across A, in one slice, keep both ends). */
    double line[MAX_EDGES][6];
    for (int e = 0; e < r->edges; e++) {
        const double *c0 = r->corner[r->edge[e][0]], *c1 = r->corner[r->edge[e][1]];
        double *l = line[e];
        l[0] = min2(c0[A], c1[A]), l[1] = max2(c0[A], c1[A]);
        if (c0[A] != c1[A]) {
            double sb = (c1[B] - c0[B]) / (c1[A] - c0[A]), sc = (c1[C] - c0[C]) / (c1[A] - c0[A]);
            l[2] = c0[B] - sb * c0[A], l[3] = sb, l[4] = c0[C] - sc * c0[A], l[5] = sc;
        } else {
            l[2] = c0[B], l[3] = c1[B], l[4] = c0[C], l[5] = c1[C];
        }
    }
    size_t stride[3] = {1, s->dims[0], s->dims[0] * s->dims[1]};
    size_t base = st->k0 * stride[2];
    const double *o = r->origin;
    for (size_t sa = from[A]; sa <= to[A]; sa++) {
        double ca = s->coord[A][sa];
        /* The slice's cross-section: where it crosses the region's edges (the slice clamped
         * into the region's span, whose planes already carry the slack), padded. */
        double cq = min2(max2(ca, lo[A]), hi[A]);
        double blo = INFINITY, bhi = -INFINITY, clo = INFINITY, chi = -INFINITY;
        for (int e = 0; e < r->edges; e++) {
            const double *l = line[e];
            if (cq < l[0] || cq > l[1])
                continue;
            if (l[0] != l[1]) {
                double b = l[2] + l[3] * cq, c = l[4] + l[5] * cq;
                blo = min2(blo, b), bhi = max2(bhi, b), clo = min2(clo, c), chi = max2(chi, c);
            } else {
                blo = min2(blo, min2(l[2], l[3])), bhi = max2(bhi, max2(l[2], l[3]));
                clo = min2(clo, min2(l[4], l[5])), chi = max2(chi, max2(l[4], l[5]));
            }
        }
        size_t b0, b1, u0, u1;
        if (blo > bhi ||
            !node_range(s, B, blo - s->row_pad, bhi + s->row_pad, from[B], to[B], &b0, &b1) ||
            !node_range(s, C, clo - s->row_pad, chi + s->row_pad, from[C], to[C], &u0, &u1))
            continue;
        for (int p = 0; p < r->planes; p++) /* the planes' offsets on this slice */
            off[p] = pl_sorted[p][4] - pl_sorted[p][0] * ca;
        const double *off_up = off, *off_down = off + n_up, *off_flat = off + n_up + n_down;
        int few = (b1 - b0 + 1) * (u1 - u0 + 1) <= FEW_POINTS;
        double d[3];
        d[A] = ca - o[A];
        for (size_t sb = b0; sb <= b1; sb++) {
            double cb = s->coord[B][sb], lo_c = -INFINITY, hi_c = INFINITY;
            int inside = 1;
            for (int p = 0; p < n_flat; p++)
                inside &= flat[p][1] * cb <= off_flat[p];
            if (!inside)
                continue;
            size_t v0 = u0, v1 = u1;
            if (!few) { /* the row's interval along C */
                for (int p = 0; p < n_up; p++)
                    hi_c = min2(hi_c, (off_up[p] - up[p][1] * cb) * up[p][3]);
                for (int p = 0; p < n_down; p++)
                    lo_c = max2(lo_c, (off_down[p] - down[p][1] * cb) * down[p][3]);
                if (!node_range(s, C, lo_c, hi_c, u0, u1, &v0, &v1))
                    continue;
            }
            d[B] = cb - o[B];
            d[C] = 0;
            /* The feature's squared distance along the row, a quadratic in the node's C:
             * face (h0 + h1 t)^2, edge |x0 + t x1|^2 (x = d x dir), vertex r0 + t^2. */
            double unit_c[3] = {0, 0, 0}, x0[3] = {0, 0, 0}, x1[3] = {0, 0, 0}, h0 = 0, h1 = 0, r0 = 0;
            unit_c[C] = 1;
            if (r->kind == FACE) {
                h0 = dot3(d, r->dir), h1 = r->dir[C];
            } else if (r->kind == EDGE) {
                cross3(x0, d, r->dir);
                cross3(x1, unit_c, r->dir);
            } else {
                r0 = dot3(d, d);
            }
            size_t row = sa * stride[A] + sb * stride[B] - base;
            for (size_t u = v0; u <= v1; u++) {
                double cc = s->coord[C][u];
                if (few) { /* the node against every plane */
                    int in = 1;
                    for (int p = 0; p < n_up + n_down; p++)
                        in &= up[p][1] * cb + up[p][2] * cc <= off_up[p];
                    if (!in)
                        continue;
                } else if (cc < lo_c || cc > hi_c) {
                    continue; /* the node's own coordinate decides */
                }
                double t = cc - o[C], d2;
                if (r->kind == FACE) {
                    double h = h0 + h1 * t;
                    d2 = h * h;
                } else if (r->kind == EDGE) {
                    double x = x0[0] + t * x1[0], y = x0[1] + t * x1[1], z = x0[2] + t * x1[2];
                    d2 = x * x + y * y + z * z;
                } else {
                    d2 = r0 + t * t;
                }
                size_t n = row + u * stride[C];
                if (d2 < best[n] || (d2 == best[n] && feature < winner[n]))
                    best[n] = d2, winner[n] = feature;
            }
        }
    }
}

static void features_range(void *ctx, size_t begin, size_t end, int worker)
{
    call_state *st = ctx;
    region *r = &st->regions[worker];
    double *best = st->best + (size_t)worker * st->nodes;
    uint32_t *winner = st->winner + (size_t)worker * st->nodes;
    for (size_t q = begin; q < end; q++) {
        uint32_t f = st->scan->order[q];
        if (build_region(st->scan, f, r))
            scan_region(st, r, f, best, winner);
    }
}

/* The exact closest point on a triangle of the winning feature: the face itself, or the
 * lowest-numbered triangle of the edge or vertex (the searches break ties the same way; the
 * others reach the same point, and the same distance when the closest point is the vertex). */
static void exact_hit(const sdf__scan *s, uint32_t feature, const double p[3], sdf__hit *hit)
{
    uint32_t tri = feature < s->faces ? feature
                   : feature < s->faces + s->edges
                       ? s->edge_tri[s->edge_first[feature - s->faces]]
                       : s->vtri[s->vtri_first[feature - s->faces - s->edges]];
    const uint32_t *t = s->mesh->triangles + 3 * (size_t)tri;
    const double *v[3] = {vertex(s, t[0]), vertex(s, t[1]), vertex(s, t[2])};
    hit->dist2 = sdf__closest_on_triangle(p, v[0], v[1], v[2], hit->point, hit->bary,
                                          &hit->feature);
    sdf__triangle_normal(v[0], v[1], v[2], hit->face_normal);
    hit->triangle = tri;
}

/* Rows of the call: the workers' winners merged, their exact distances, then sdf_query's own
 * sign and output. */
static void rows_range(void *ctx, size_t begin, size_t end, int worker)
{
    call_state *st = ctx;
    const sdf__scan *s = st->scan;
    size_t nx = s->dims[0], ny = s->dims[1];
    float *points = st->points + (size_t)worker * nx * 3;
    sdf__hit *hits = st->hits + (size_t)worker * nx;
    for (size_t row = begin; row < end; row++) {
        size_t j = row % ny, k = st->k0 + row / ny, first = row * nx;
        for (size_t i = 0; i < nx; i++) {
            double p[3] = {s->coord[0][i], s->coord[1][j], s->coord[2][k]};
            for (int a = 0; a < 3; a++)
                points[3 * i + a] = (float)p[a];
            double estimate = INFINITY;
            uint32_t w = UINT32_MAX;
            for (int t = 0; t < st->workers; t++) {
                size_t n = (size_t)t * st->nodes + first + i;
                if (st->best[n] < estimate || (st->best[n] == estimate && st->winner[n] < w))
                    estimate = st->best[n], w = st->winner[n];
            }
            hits[i].dist2 = INFINITY;
            if (w == UINT32_MAX)
                continue;
            exact_hit(s, w, p, &hits[i]);
            /* Inside its region a feature's estimate is its exact distance; more means the
             * node was an extra candidate's (within the slack): search it instead. */
            if (hits[i].dist2 - estimate > 1e-12 * hits[i].dist2 + 1e-24 * s->scale2)
                hits[i].dist2 = INFINITY;
        }
        sdf_query_result res = {.distance = st->out + first};
        sdf__query_finish(s->mesh, points, hits, nx, &s->query, &res);
    }
}

size_t sdf__scan_slices_per_call(const sdf__scan *s)
{
    size_t workers = (size_t)sdf__effective_threads(s->query.threads, s->features, 1);
    size_t per_node = workers * (sizeof(double) + sizeof(uint32_t));
    size_t slices = SCAN_BUDGET_BYTES / per_node / (s->dims[0] * s->dims[1]);
    return slices ? slices : 1;
}

int sdf__scan_slices(sdf__scan *s, size_t k0, size_t k1, float *out)
{
    size_t nx = s->dims[0], rows = (k1 - k0) * s->dims[1];
    int workers = sdf__effective_threads(s->query.threads, s->features, FEATURE_CHUNK);
    size_t w = (size_t)workers, nodes = rows * nx;
    call_state st = {s, k0, k1, nodes, malloc(w * nodes * sizeof(double)),
                     malloc(w * nodes * sizeof(uint32_t)), malloc(w * sizeof(region)),
                     malloc(w * nx * 3 * sizeof(float)), malloc(w * nx * sizeof(sdf__hit)),
                     workers, out};
    int rc = st.best && st.winner && st.regions && st.points && st.hits ? 0 : SDF_ENOMEM;
    if (!rc) {
        for (size_t n = 0; n < w * nodes; n++)
            st.best[n] = INFINITY, st.winner[n] = UINT32_MAX;
        sdf__parallel_for(s->features, FEATURE_CHUNK, workers, features_range, &st);
        sdf__parallel_for(rows, 8, workers, rows_range, &st);
    }
    free(st.best), free(st.winner), free(st.regions), free(st.points), free(st.hits);
    return rc;
}

/* ---- set-up ------------------------------------------------------------------------------ */

/* Counting sort of (key, value) pairs into a CSR list: first[key]..first[key + 1]. */
static int csr(size_t keys, size_t pairs, const uint32_t *key, const uint32_t *value,
               uint32_t **first_out, uint32_t **list_out)
{
    uint32_t *first = calloc(keys + 1, sizeof *first), *list = malloc((pairs + 1) * sizeof *list);
    if (!first || !list) {
        free(first), free(list);
        return SDF_ENOMEM;
    }
    for (size_t p = 0; p < pairs; p++)
        first[key[p] + 1]++;
    for (size_t k = 0; k < keys; k++)
        first[k + 1] += first[k];
    uint32_t *fill = malloc((keys + 1) * sizeof *fill);
    if (!fill) {
        free(first), free(list);
        return SDF_ENOMEM;
    }
    memcpy(fill, first, (keys + 1) * sizeof *fill);
    for (size_t p = 0; p < pairs; p++)
        list[fill[key[p]]++] = value[p];
    free(fill);
    *first_out = first, *list_out = list;
    return 0;
}

static int adjacency(sdf__scan *s)
{
    const sdf_mesh *m = s->mesh;
    size_t t3 = 3 * s->faces;
    uint32_t *key = malloc((t3 + 1) * sizeof *key), *val = malloc((2 * t3 + 1) * sizeof *val);
    uint32_t *key2 = malloc((2 * t3 + 1) * sizeof *key2);
    s->edge_end = malloc((2 * s->edges + 1) * sizeof *s->edge_end);
    int rc = key && val && key2 && s->edge_end ? 0 : SDF_ENOMEM;
    if (!rc) {
        for (size_t c = 0; c < t3; c++) { /* each triangle's edges, and their ends */
            uint32_t e = m->edge_of[c];
            key[c] = e, val[c] = (uint32_t)(c / 3);
            uint32_t a = m->triangles[c], b = m->triangles[c - c % 3 + (c % 3 + 1) % 3];
            s->edge_end[2 * e] = a < b ? a : b, s->edge_end[2 * e + 1] = a < b ? b : a;
        }
        rc = csr(s->edges, t3, key, val, &s->edge_first, &s->edge_tri);
    }
    if (!rc) { /* every edge is a neighbour relation both ways */
        for (size_t e = 0; e < s->edges; e++) {
            key2[2 * e] = s->edge_end[2 * e], val[2 * e] = s->edge_end[2 * e + 1];
            key2[2 * e + 1] = s->edge_end[2 * e + 1], val[2 * e + 1] = s->edge_end[2 * e];
        }
        rc = csr(s->vertices, 2 * s->edges, key2, val, &s->vert_first, &s->vert_nbr);
    }
    if (!rc) {
        for (size_t c = 0; c < t3; c++)
            val[c] = (uint32_t)(c / 3);
        rc = csr(s->vertices, t3, m->triangles, val, &s->vtri_first, &s->vtri);
    }
    free(key), free(val), free(key2);
    return rc;
}

/* How far from the surface a node can be, from exact distances on every COARSE_STEP-th node:
 * a node is within half a coarse cell's diagonal of one of them. On a closed, consistently
 * outward mesh the two sides are bounded apart (a point whose closest point is on a face's
 * front lies outside). */
static int reaches(sdf__scan *s)
{
    size_t n[3], count = 1;
    for (int a = 0; a < 3; a++) {
        n[a] = (s->dims[a] - 1 + COARSE_STEP - 1) / COARSE_STEP + 1;
        count *= n[a];
    }
    float *pts = malloc(count * 3 * sizeof *pts), *f = malloc(count * sizeof *f);
    if (!pts || !f) {
        free(pts), free(f);
        return SDF_ENOMEM;
    }
    size_t q = 0;
    for (size_t k = 0; k < n[2]; k++)
        for (size_t j = 0; j < n[1]; j++)
            for (size_t i = 0; i < n[0]; i++, q++) {
                size_t idx[3] = {i, j, k};
                for (int a = 0; a < 3; a++) {
                    size_t node = idx[a] * COARSE_STEP;
                    pts[3 * q + a] = (float)s->coord[a][node < s->dims[a] ? node : s->dims[a] - 1];
                }
            }
    int sided = s->mesh->report.auto_sign == SDF_SIGN_PSEUDONORMAL;
    sdf_query_options o = {.sign = sided ? SDF_SIGN_PSEUDONORMAL : SDF_SIGN_NONE,
                           .threads = s->query.threads};
    sdf_query_result res = {.distance = f};
    int rc = sdf_query(s->mesh, pts, count, &o, &res);
    double outside = 0, inside = 0, half_diag = 0;
    for (int a = 0; a < 3; a++)
        half_diag += (0.5 * COARSE_STEP * s->spacing[a]) * (0.5 * COARSE_STEP * s->spacing[a]);
    for (size_t p = 0; !rc && p < count; p++) {
        outside = max2(outside, f[p]);
        inside = max2(inside, -f[p]);
    }
    /* Widened past the float rounding of the coarse distances. */
    double widen = sqrt(half_diag) * (1 + 1e-6) + s->slack;
    s->reach_front = (sided ? outside : max2(outside, inside)) * (1 + 1e-6) + widen;
    s->reach_back = (sided ? inside : max2(outside, inside)) * (1 + 1e-6) + widen;
    free(pts), free(f);
    return rc;
}

/* The visit order of the features: faces at their centroids, edges at their midpoints. */
static int feature_order(sdf__scan *s)
{
    float *at = malloc((3 * s->features + 1) * sizeof *at);
    s->order = malloc((s->features + 1) * sizeof *s->order);
    if (!at || !s->order) {
        free(at);
        return SDF_ENOMEM;
    }
    for (size_t f = 0; f < s->features; f++) {
        const uint32_t *ends;
        uint32_t one;
        int n;
        if (f < s->faces)
            ends = s->mesh->triangles + 3 * f, n = 3;
        else if (f < s->faces + s->edges)
            ends = s->edge_end + 2 * (f - s->faces), n = 2;
        else
            one = (uint32_t)(f - s->faces - s->edges), ends = &one, n = 1;
        for (int a = 0; a < 3; a++) {
            double sum = 0;
            for (int c = 0; c < n; c++)
                sum += vertex(s, ends[c])[a];
            at[3 * f + a] = (float)(sum / n);
        }
    }
    int rc = sdf__morton_order((const char *)at, 3 * sizeof(float), s->features, s->order);
    free(at);
    return rc;
}

int sdf__scan_supported(const sdf_mesh *mesh, sdf_sign_method sign)
{
    if (sign == SDF_SIGN_AUTO)
        sign = mesh->report.auto_sign;
    if (!mesh->report.closed || mesh->report.triangles == 0 ||
        (sign != SDF_SIGN_PSEUDONORMAL && sign != SDF_SIGN_NONE))
        return 0;
    for (size_t c = 0; c < 3 * mesh->report.triangles; c++)
        if (mesh->edge_of[c] == SDF__NO_EDGE)
            return 0;
    return 1;
}

int sdf__scan_create(const sdf_mesh *mesh, const sdf_volume_info *info,
                     const sdf_query_options *opts, sdf__scan **out)
{
    sdf__scan *s = calloc(1, sizeof *s);
    if (!s)
        return SDF_ENOMEM;
    s->mesh = mesh;
    s->query = *opts;
    s->query.point_stride = 0;
    s->faces = mesh->report.triangles;
    s->edges = mesh->edge_count;
    s->vertices = mesh->report.vertices;
    s->features = s->faces + s->edges + s->vertices;
    double extent = mesh->report.diagonal;
    for (int a = 0; a < 3; a++) {
        s->dims[a] = info->dims[a];
        s->origin[a] = info->origin[a];
        s->spacing[a] = info->spacing[a];
        double far = (double)(info->dims[a] - 1) * info->spacing[a];
        extent = max2(extent, max2(fabs(info->origin[a]), fabs(info->origin[a] + far)));
        extent = max2(extent, max2(fabs(mesh->report.bbox_min[a]), fabs(mesh->report.bbox_max[a])));
    }
    /* Double rounding of a plane's value is ~1e-16 of the coordinates; node coordinates are
     * used as the exact floats they are. */
    s->slack = 1e-12 * extent;
    s->row_pad = 1e-6 * extent;
    s->scale2 = extent * extent;
    int rc = 0;
    for (int a = 0; a < 3; a++) {
        double far = fmax(fabs(info->origin[a]),
                          fabs(info->origin[a] + (double)(info->dims[a] - 1) * info->spacing[a]));
        s->inv_spacing[a] = 1 / info->spacing[a];
        s->index_slack[a] = 2 * FLT_EPSILON * far / info->spacing[a] + 1e-9;
    }
    for (int a = 0; a < 3 && !rc; a++) {
        s->coord[a] = malloc(s->dims[a] * sizeof(double));
        if (!s->coord[a])
            rc = SDF_ENOMEM;
        for (size_t i = 0; !rc && i < s->dims[a]; i++)
            s->coord[a][i] = (float)(info->origin[a] + (double)i * info->spacing[a]);
    }
    s->pos = rc ? NULL : malloc(3 * s->vertices * sizeof(double));
    if (!rc && !s->pos)
        rc = SDF_ENOMEM;
    for (size_t i = 0; !rc && i < 3 * s->vertices; i++)
        s->pos[i] = mesh->positions[i];
    if (!rc)
        rc = adjacency(s);
    if (!rc)
        rc = reaches(s);
    if (!rc)
        rc = feature_order(s);
    if (rc) {
        sdf__scan_destroy(s);
        return rc;
    }
    *out = s;
    return 0;
}

void sdf__scan_destroy(sdf__scan *s)
{
    if (!s)
        return;
    for (int a = 0; a < 3; a++)
        free(s->coord[a]);
    free(s->pos), free(s->edge_end), free(s->edge_first), free(s->edge_tri);
    free(s->vert_first), free(s->vert_nbr), free(s->vtri_first), free(s->vtri);
    free(s->order);
    free(s);
}
