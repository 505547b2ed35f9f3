/* regions.c - closest-point regions of a closed mesh's features (see regions.h).
 *
 * Each region is a necessary condition on a point whose closest surface point lies on the
 * feature, widened by a rounding slack: a region can only hold too many points, never miss
 * one. Bounds come from the same geometry: prisms are capped at the reach, a wedge's sector
 * sits in a triangle or a rectangle, a cone in the pyramid of its generators (the planes'
 * pairwise intersections that satisfy every plane) or, when wide, in a box. */
#include <float.h>
#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/parallel.h"
#include "mesh/mesh.h"
#include "points/points.h"
#include "geom/triangle.h"
#include "sign/pseudonormal.h"
#include "scan/regions.h"

/* Corners 0-2 and 3-5 of a triangular prism are its two ends, i and i + 3 joined. */
static const uint8_t prism_edges[9][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5},
                                          {5, 3}, {0, 3}, {1, 4}, {2, 5}};

static double normalize3(double v[3])
{
    double len = sqrt(sdf__dot3(v, v));
    if (len > 0)
        for (int a = 0; a < 3; a++)
            v[a] /= len;
    return len;
}

static void add_plane(const sdf__features *s, sdf__region *r, const double n[3], double c)
{
    if (r->planes == SDF__REGION_PLANES)
        return; /* fewer planes: a larger region, still holding every node it must */
    double *p = r->plane[r->planes++];
    p[0] = n[0], p[1] = n[1], p[2] = n[2], p[3] = c + s->slack;
}

/* The plane n . (p - at) <= offset. */
static void add_plane_at(const sdf__features *s, sdf__region *r, const double n[3],
                         const double at[3], double offset)
{
    add_plane(s, r, n, sdf__dot3(n, at) + offset);
}

static const double *vertex(const sdf__features *s, uint32_t v)
{
    return s->pos + 3 * (size_t)v;
}

/* The least t at which surface point c has beaten every point of a region at distance t
 * from its feature, given that those points lie within `offset` + `spread` t of base + t
 * axis (u = base - c, axis a unit vector): |u + t axis| + offset + spread t < t, solved as
 * a quadratic; INFINITY if it never holds. The root is checked in the inequality itself,
 * with a margin over its rounding. */
static double cut_by_point(const double u[3], const double axis[3], double offset,
                           double spread)
{
    double k = 1 - spread, ua = sdf__dot3(u, axis), uu = sdf__dot3(u, u);
    /* |u + t axis| >= |ua + t|, so it takes ua < -offset - spread t: c ahead of the base. */
    if (!(ua < -offset))
        return INFINITY;
    /* (k t - offset)^2 > |u|^2 + 2 t (u . axis) + t^2 with k t > offset:
     * qa t^2 + qb t + qc > 0. */
    double qa = k * k - 1, qb = -2 * (k * offset + ua), qc = offset * offset - uu;
    double lo, hi = INFINITY;
    if (qa == 0) { /* no spread: linear */
        if (!(qb > 0))
            return INFINITY;
        lo = -qc / qb;
    } else { /* qa < 0: positive between the roots */
        double disc = qb * qb - 4 * qa * qc;
        if (!(disc > 0))
            return INFINITY;
        double root = sqrt(disc), r1 = (-qb + root) / (2 * qa), r2 = (-qb - root) / (2 * qa);
        lo = sdf__min2(r1, r2), hi = sdf__max2(r1, r2);
    }
    double t = sdf__max2(sdf__max2(lo, offset / k), 0.0);
    t += 1e-9 * (t + sqrt(uu) + offset);
    if (!(t < hi))
        return INFINITY;
    double q[3] = {u[0] + t * axis[0], u[1] + t * axis[1], u[2] + t * axis[2]};
    double margin = 1e-12 * (t + sqrt(uu) + offset);
    return sqrt(sdf__dot3(q, q)) + offset + spread * t + margin < t ? t : INFINITY;
}

/* How far along `axis` from `base` a region can hold nodes its feature is closest to, at most
 * `reach`. The region's points at distance t from the feature lie within offset + spread t
 * of base + t axis; once some surface point is nearer to every one of them than t, the
 * feature has lost them and every farther point on their rays (a point's closest point is
 * the closest point of every point between them too, so a feature that loses a point loses
 * the rest of its ray). The surface points tried are the closest points of the coarse nodes
 * nearest the axis, one per step of the march, each solved for exactly where it wins
 * (cut_by_point), so the cut is not rounded up to a step. Before, the bound at each step was
 * the nearest node's distance plus the way there, up to half a coarse cell's diagonal
 * looser, so the scan evaluated more nodes (all eight corners of a cell were hardly
 * tighter, and cost more than they saved). */
static double truncate_reach(const sdf__features *s, const double base[3], const double axis[3],
                             double offset, double spread, double reach)
{
    if (spread >= 0.5 || !s->bound)
        return reach;
    /* The points are floats near the surface: widen by how far they may lie from it. */
    double widened = offset + s->bound_point_error + s->slack, best = reach;
    /* A coarse cell of the finest axis a step, but no more steps than twice the coarse
     * lattice's nodes along its three axes: bounds far longer on one axis than another (a
     * box 2e6 by 1 by 1 around a unit mesh) made millions of steps a region, a 64^3 bake
     * for minutes. A cube's regions (at most its diagonal long, ~28 coarse cells at 17 nodes
     * per axis) still step a cell at a time. Longer steps only cut a region later, which is
     * always safe. */
    double most_steps = 2.0 * (double)(s->bound_dims[0] + s->bound_dims[1] + s->bound_dims[2]);
    double step = sdf__max2(s->march, reach / most_steps);
    for (double t = 0; t < best; t += step) {
        size_t at = 0, scale = 1;
        for (int a = 0; a < 3; a++) { /* the nearest coarse node */
            double c = (base[a] + t * axis[a] - s->bound_coord[a][0]) * s->bound_inv_step[a];
            size_t last = s->bound_dims[a] - 1;
            size_t i = c + 0.5 <= 0 ? 0 : c + 0.5 >= (double)last ? last : (size_t)(c + 0.5);
            at += i * scale;
            scale *= s->bound_dims[a];
        }
        const float *c = s->bound_point + 3 * at;
        double u[3] = {base[0] - c[0], base[1] - c[1], base[2] - c[2]};
        best = sdf__min2(best, cut_by_point(u, axis, widened, spread));
    }
    return best;
}

/* Corners at + t m + w q + e d for the given ranges: an oriented box, with its 12 edges. */
static void box_corners(sdf__region *r, const double at[3], const double m[3], const double t[2],
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
static int face_region(const sdf__features *s, size_t t, sdf__region *r)
{
    const uint32_t *tri = s->triangles + 3 * t;
    const double *v[3] = {vertex(s, tri[0]), vertex(s, tri[1]), vertex(s, tri[2])};
    double n[3];
    sdf__triangle_normal(v[0], v[1], v[2], n);
    if (normalize3(n) == 0)
        return 0; /* no area: its points are its edges' */
    r->kind = SDF__REGION_FACE;
    memcpy(r->origin, v[0], sizeof r->origin);
    memcpy(r->dir, n, sizeof r->dir);
    memcpy(r->sign_dir, n, sizeof r->sign_dir);
    r->planes = 0;
    for (int q = 0; q < 3; q++) {
        double e[3], m[3];
        for (int a = 0; a < 3; a++)
            e[a] = v[(q + 1) % 3][a] - v[q][a];
        sdf__cross3(m, e, n); /* outward in the face's plane */
        if (normalize3(m) > 0)
            add_plane_at(s, r, m, v[q], 0);
    }
    double centre[3], radius = 0, minus_n[3] = {-n[0], -n[1], -n[2]};
    for (int a = 0; a < 3; a++)
        centre[a] = (v[0][a] + v[1][a] + v[2][a]) / 3;
    for (int q = 0; q < 3; q++) {
        double g[3] = {v[q][0] - centre[0], v[q][1] - centre[1], v[q][2] - centre[2]};
        radius = sdf__max2(radius, sqrt(sdf__dot3(g, g)));
    }
    double front = truncate_reach(s, centre, n, radius, 0, s->reach_front);
    double back = truncate_reach(s, centre, minus_n, radius, 0, s->reach_back);
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

/* The planes of edge e's incident faces (from a along the unit direction d): for each face
 * with area, its unit direction u across the edge, a plane u . (p - a) <= 0 of r. The first
 * two faces' u and unit normals are kept. Returns how many faces had area. */
static int edge_face_planes(const sdf__features *s, size_t e, const double a[3],
                            const double d[3], sdf__region *r, double u[2][3],
                            double normals[2][3])
{
    int valid = 0;
    for (uint32_t k = s->edge_first[e]; k < s->edge_first[e + 1]; k++) {
        const uint32_t *tri = s->triangles + 3 * (size_t)s->edge_tri[k];
        uint32_t c = tri[0];
        for (int q = 1; q < 3; q++)
            if (c == s->edge_end[2 * e] || c == s->edge_end[2 * e + 1])
                c = tri[q];
        double w[3], uf[3];
        for (int x = 0; x < 3; x++)
            w[x] = vertex(s, c)[x] - a[x];
        double along = sdf__dot3(w, d);
        for (int x = 0; x < 3; x++)
            uf[x] = w[x] - along * d[x];
        if (normalize3(uf) == 0)
            continue; /* a zero-area face does not bound the edge's region */
        add_plane_at(s, r, uf, a, 0);
        if (valid < 2) {
            memcpy(u[valid], uf, sizeof uf);
            sdf__triangle_normal(vertex(s, tri[0]), vertex(s, tri[1]), vertex(s, tri[2]),
                                 normals[valid]);
            normalize3(normals[valid]);
        }
        valid++;
    }
    return valid;
}

/* The wedge's cross-section before truncation: t in [t0, t1] along the unit m, |w| <=
 * *half_width across it, from the faces' directions u and normals (valid of them). */
static void edge_section(const sdf__features *s, const double d[3], const double u[2][3],
                         const double normals[2][3], int valid, double m[3], double t[2],
                         double *half_width)
{
    double reach = sdf__max2(s->reach_front, s->reach_back);
    if (valid == 2) { /* a closed mesh's edge has two faces */
        double sum[3] = {u[0][0] + u[1][0], u[0][1] + u[1][1], u[0][2] + u[1][2]};
        double spread = sqrt(sdf__dot3(sum, sum)); /* 2 cos(beta / 2), beta between u0 and u1 */
        if (spread >= 1e-6) {                 /* a sector of angle pi - beta around -sum */
            for (int x = 0; x < 3; x++)
                m[x] = -sum[x] / spread;
            double side = sdf__dot3(m, normals[0]) + sdf__dot3(m, normals[1]);
            reach = side > 0 ? s->reach_front : s->reach_back;
            t[0] = 0, t[1] = reach;
            *half_width = reach * sdf__min2(1.0, 0.5 * spread);
        } else { /* flat: the plane of the normals, both sides */
            memcpy(m, normals[0], 3 * sizeof *m);
            t[0] = -s->reach_back, t[1] = s->reach_front;
            *half_width = reach * spread;
        }
    } else { /* a face without area beside it: a cylinder around the edge */
        double any[3] = {1, 0, 0};
        if (fabs(d[0]) > 0.9)
            any[0] = 0, any[1] = 1;
        sdf__cross3(m, d, any);
        normalize3(m);
        t[0] = -reach, t[1] = reach, *half_width = reach;
    }
}

/* A sector of half-angle gamma <= 60 degrees (sin_g its sine) reaching t1 along m: inside
 * the triangle (0, 0), (t1, +-t1 tan gamma) of the (m, q) plane, its sides the faces'
 * planes; the prism of that triangle along the edge (a, direction d, length len). */
static void edge_prism(sdf__region *r, const double a[3], const double d[3], double len,
                       const double m[3], const double q[3], double t1, double sin_g)
{
    double spread_w = t1 * sin_g / sqrt(1 - sin_g * sin_g);
    r->corners = 6;
    for (int end = 0; end < 2; end++)
        for (int x = 0; x < 3; x++) {
            double at = a[x] + (end ? len : 0) * d[x];
            r->corner[3 * end][x] = at;
            r->corner[3 * end + 1][x] = at + t1 * m[x] - spread_w * q[x];
            r->corner[3 * end + 2][x] = at + t1 * m[x] + spread_w * q[x];
        }
    r->edges = 9;
    memcpy(r->edge, prism_edges, sizeof prism_edges);
}

/* The wedge beside edge e: points whose foot on the edge's line lies on the edge and which
 * lie on no incident face's side of the edge. Its cross-section, a sector of the reach's
 * radius, is bounded by a triangle (narrow sectors) or a rectangle. */
static int edge_region(const sdf__features *s, size_t e, sdf__region *r)
{
    const double *a = vertex(s, s->edge_end[2 * e]), *b = vertex(s, s->edge_end[2 * e + 1]);
    double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double len = normalize3(d);
    if (len == 0)
        return 0;
    r->kind = SDF__REGION_EDGE;
    memcpy(r->origin, a, sizeof r->origin);
    memcpy(r->dir, d, sizeof r->dir);
    for (int x = 0; x < 3; x++)
        r->sign_dir[x] = s->edge_normal[3 * e + (size_t)x];
    r->planes = 0;
    double minus_d[3] = {-d[0], -d[1], -d[2]};
    add_plane_at(s, r, minus_d, a, 0);
    add_plane_at(s, r, d, b, 0);
    double u[2][3], normals[2][3], m[3], t[2], half_width;
    int valid = edge_face_planes(s, e, a, d, r, u, normals);
    edge_section(s, d, (const double (*)[3])u, (const double (*)[3])normals, valid, m, t,
                 &half_width);
    /* Truncated where the bound shows the edge has lost: the sector's points at distance t
     * lie within len / 2 + 2 sin(gamma / 2) t of mid + t m. */
    double mid[3] = {0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])};
    double sin_g = t[1] > 0 ? sdf__min2(1.0, half_width / sdf__max2(t[1], -t[0])) : 1;
    double spread = sqrt(sdf__max2(0.0, 2 - 2 * sqrt(1 - sin_g * sin_g)));
    double minus_m[3] = {-m[0], -m[1], -m[2]};
    if (t[1] > 0)
        t[1] = truncate_reach(s, mid, m, 0.5 * len, spread, t[1]);
    if (t[0] < 0)
        t[0] = -truncate_reach(s, mid, minus_m, 0.5 * len, spread, -t[0]);
    half_width = sdf__max2(t[1], -t[0]) * sin_g;
    double q[3], minus_q[3];
    sdf__cross3(q, d, m);
    for (int x = 0; x < 3; x++)
        minus_q[x] = -q[x];
    add_plane_at(s, r, m, a, t[1]);
    if (t[0] == 0 && sin_g <= 0.866) {
        edge_prism(r, a, d, len, m, q, t[1], sin_g);
        return 1;
    }
    add_plane_at(s, r, minus_m, a, -t[0]);
    add_plane_at(s, r, q, a, half_width);
    add_plane_at(s, r, minus_q, a, half_width);
    double ends[2] = {0, len};
    box_corners(r, a, m, t, q, half_width, d, ends);
    return 1;
}

/* A vertex whose edges all lie in one plane and surround it (flat CAD surfaces): its cone is
 * the plane's normal line. A point at lateral offset b from the line has b . e_j >=
 * |b| cos(gap / 2) for some edge (gap: the widest angle between neighbouring edges), so the
 * slack-widened planes hold only points within (slack + reach tilt) / cos(gap / 2) of it:
 * a thin box, truncated on both sides. 0 if the vertex is not such a line. */
static int flat_vertex(const sdf__features *s, const double p[3], const double (*e)[3], int n,
                       const double (*gen)[3], int g, double reach, sdf__region *r)
{
    int line = -1;
    for (int h = 1; h < g && line < 0; h++)
        for (int k = 0; k < h && line < 0; k++)
            if (sdf__dot3(gen[h], gen[k]) < -1 + 1e-9)
                line = h;
    if (line < 0 || n < 3)
        return 0;
    const double *l = gen[line];
    double b1[3], b2[3], any[3] = {1, 0, 0}, angle[SDF__REGION_PLANES], tilt = 0;
    if (fabs(l[0]) > 0.9)
        any[0] = 0, any[1] = 1;
    sdf__cross3(b1, l, any);
    normalize3(b1);
    sdf__cross3(b2, l, b1);
    for (int j = 0; j < n; j++) {
        tilt = sdf__max2(tilt, fabs(sdf__dot3(e[j], l)));
        angle[j] = atan2(sdf__dot3(e[j], b2), sdf__dot3(e[j], b1));
    }
    for (int j = 1; j < n; j++) /* insertion sort */
        for (int k = j; k > 0 && angle[k - 1] > angle[k]; k--) {
            double t = angle[k];
            angle[k] = angle[k - 1], angle[k - 1] = t;
        }
    double gap = angle[0] + 2 * M_PI - angle[n - 1];
    for (int j = 1; j < n; j++)
        gap = sdf__max2(gap, angle[j] - angle[j - 1]);
    if (gap > M_PI - 0.01)
        return 0;
    double width = 2 * (s->slack + reach * tilt) / cos(0.5 * gap) + s->row_pad;
    double minus_l[3] = {-l[0], -l[1], -l[2]};
    double span[2] = {-truncate_reach(s, p, minus_l, width, 0, reach),
                      truncate_reach(s, p, l, width, 0, reach)};
    double ends[2] = {-width, width};
    box_corners(r, p, l, span, b1, width, b2, ends);
    return 1;
}

/* Vertex v's unit edge directions (to its neighbours; at most SDF__REGION_PLANES - 2), each
 * also a plane x . (w - v) <= 0 of r. Returns how many. */
static int vertex_edges(const sdf__features *s, size_t v, const double p[3], sdf__region *r,
                        double e[][3])
{
    uint32_t first = s->vert_first[v], count = s->vert_first[v + 1] - first;
    int n = 0;
    for (uint32_t k = 0; k < count && n < SDF__REGION_PLANES - 2; k++) {
        const double *w = vertex(s, s->vert_nbr[first + k]);
        double dir[3] = {w[0] - p[0], w[1] - p[1], w[2] - p[2]};
        if (normalize3(dir) == 0)
            continue;
        memcpy(e[n], dir, sizeof dir);
        add_plane_at(s, r, dir, p, 0);
        n++;
    }
    return n;
}

/* The cone's generators: the unit pairwise intersections of the n planes (normals e) that
 * satisfy every plane, each once. Returns how many; *pointed becomes 0 when there are more
 * than a region's corners hold. */
static int cone_generators(const double e[][3], int n, double gen[][3], int *pointed)
{
    int g = 0;
    for (int i = 0; i < n && *pointed; i++)
        for (int j = i + 1; j < n && *pointed; j++) {
            double ray[3];
            sdf__cross3(ray, e[i], e[j]);
            double len = sqrt(sdf__dot3(ray, ray));
            if (len < 1e-9)
                continue;
            /* The ray and its opposite against every plane in one pass, before the ray is
             * made a unit vector, so the pairs that fail (most of them) skip its divisions:
             * the opposite's products are the ray's negated, exactly. */
            int ok_minus = 1, ok_plus = 1;
            double tolerance = 1e-9 * len;
            for (int l = 0; l < n && (ok_minus || ok_plus); l++) {
                double along = sdf__dot3(ray, e[l]);
                ok_minus &= -along <= tolerance, ok_plus &= along <= tolerance;
            }
            if (!ok_minus && !ok_plus)
                continue;
            for (int a = 0; a < 3; a++)
                ray[a] /= len;
            for (int sign = -1; sign <= 1; sign += 2) {
                double cand[3] = {sign * ray[0], sign * ray[1], sign * ray[2]};
                int ok = sign < 0 ? ok_minus : ok_plus;
                for (int h = 0; h < g && ok; h++)
                    ok = sdf__dot3(cand, gen[h]) < 1 - 1e-12; /* a repeat */
                if (!ok)
                    continue;
                if (g == SDF__REGION_CORNERS - 1) {
                    *pointed = 0;
                    break;
                }
                memcpy(gen[g++], cand, sizeof cand);
            }
        }
    return g;
}

/* Order the generators around the axis, so the base polygon's edges are neighbours. */
static void order_around(double gen[][3], int g, const double axis[3])
{
    double b1[3], b2[3], any[3] = {1, 0, 0}, angle[SDF__REGION_CORNERS - 1];
    if (fabs(axis[0]) > 0.9)
        any[0] = 0, any[1] = 1;
    sdf__cross3(b1, axis, any);
    normalize3(b1);
    sdf__cross3(b2, axis, b1);
    for (int h = 0; h < g; h++) { /* a pseudo-angle: monotone in the angle, no atan2 */
        double x = sdf__dot3(gen[h], b1), y = sdf__dot3(gen[h], b2), l1 = fabs(x) + fabs(y);
        double q = l1 > 0 ? x / l1 : 1;
        angle[h] = y >= 0 ? 1 - q : 3 + q;
    }
    for (int h = 1; h < g; h++) /* insertion sort: a handful of generators */
        for (int k = h; k > 0 && angle[k - 1] > angle[k]; k--) {
            double ta = angle[k], tg[3];
            angle[k] = angle[k - 1], angle[k - 1] = ta;
            memcpy(tg, gen[k], sizeof tg);
            memcpy(gen[k], gen[k - 1], sizeof tg);
            memcpy(gen[k - 1], tg, sizeof tg);
        }
}

/* The pyramid from apex p along the ordered generators to the cap at `reach` along the
 * axis: its corners (the apex first) and edges. */
static void cone_pyramid(sdf__region *r, const double p[3], const double gen[][3], int g,
                         const double axis[3], double reach)
{
    assert(g >= 1 && g + 1 <= SDF__REGION_CORNERS && 2 * g <= SDF__REGION_EDGES);
    r->corners = g + 1;
    memcpy(r->corner[0], p, sizeof r->corner[0]);
    r->edges = 0;
    for (int h = 0; h < g; h++) {
        double len = reach / sdf__dot3(gen[h], axis);
        for (int a = 0; a < 3; a++)
            r->corner[h + 1][a] = p[a] + len * gen[h][a];
        r->edge[r->edges][0] = 0, r->edge[r->edges][1] = (uint8_t)(h + 1), r->edges++;
        if (g > 1) {
            r->edge[r->edges][0] = (uint8_t)(h + 1);
            r->edge[r->edges][1] = (uint8_t)((h + 1) % g + 1);
            r->edges++;
        }
    }
}

/* A wide cone's cap reaches far out: its corners become their box within the reach's cube
 * around p. */
static void clip_wide_cone(sdf__region *r, const double p[3], double reach)
{
    double lo[3], hi[3], unit[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int a = 0; a < 3; a++) {
        lo[a] = hi[a] = p[a];
        for (int c = 1; c < r->corners; c++) {
            lo[a] = sdf__min2(lo[a], r->corner[c][a]);
            hi[a] = sdf__max2(hi[a], r->corner[c][a]);
        }
        lo[a] = sdf__max2(lo[a], p[a] - reach), hi[a] = sdf__min2(hi[a], p[a] + reach);
    }
    double span_x[2] = {lo[0], hi[0]}, span_z[2] = {lo[2], hi[2]};
    double origin[3] = {0, 0.5 * (lo[1] + hi[1]), 0};
    box_corners(r, origin, unit[0], span_x, unit[1], 0.5 * (hi[1] - lo[1]), unit[2], span_z);
}

/* The cone at vertex v: directions x with x . (w - v) <= 0 for every neighbour w. Its
 * generators are the planes' pairwise intersections that satisfy every plane; the region is
 * the pyramid they span, capped at the reach along its axis. */
static int vertex_region(const sdf__features *s, size_t v, sdf__region *r)
{
    const double *p = vertex(s, (uint32_t)v);
    if (s->vert_first[v + 1] == s->vert_first[v])
        return 0;
    r->kind = SDF__REGION_VERTEX;
    memcpy(r->origin, p, sizeof r->origin);
    for (int a = 0; a < 3; a++)
        r->sign_dir[a] = s->vertex_normal[3 * v + (size_t)a];
    r->planes = 0;
    double e[SDF__REGION_PLANES][3];
    int n = vertex_edges(s, v, p, r, e);
    double gen[SDF__REGION_CORNERS - 1][3], axis[3] = {0, 0, 0};
    int pointed = 1, g = cone_generators((const double (*)[3])e, n, gen, &pointed);
    if (g == 0 && pointed)
        return 0; /* the cone is the vertex itself (or a line its faces' regions border) */
    for (int h = 0; h < g; h++)
        for (int a = 0; a < 3; a++)
            axis[a] += gen[h][a];
    pointed = pointed && normalize3(axis) > 1e-9;
    for (int h = 0; h < g && pointed; h++)
        pointed = sdf__dot3(gen[h], axis) >= 0.05;
    double reach = sdf__max2(s->reach_front, s->reach_back);
    if (!pointed) { /* a line (a flat vertex), or a cone too wide: a cube of the reach */
        if (flat_vertex(s, p, e, n, gen, g, reach, r))
            return 1;
        double x[3] = {1, 0, 0}, y[3] = {0, 1, 0}, z[3] = {0, 0, 1}, span[2] = {-reach, reach};
        box_corners(r, p, x, span, y, reach, z, span);
        return 1;
    }
    double side = sdf__dot3(r->sign_dir, axis); /* the side the cone opens to */
    double widest = 1; /* cos of the largest angle between a generator and the axis */
    for (int h = 0; h < g; h++)
        widest = sdf__min2(widest, sdf__dot3(gen[h], axis));
    reach = truncate_reach(s, p, axis, 0, sqrt(sdf__max2(0.0, 2 - 2 * widest)),
                           side > 0 ? s->reach_front : s->reach_back);
    add_plane_at(s, r, axis, p, reach);
    order_around(gen, g, axis);
    cone_pyramid(r, p, (const double (*)[3])gen, g, axis, reach);
    if (widest < 0.5)
        clip_wide_cone(r, p, reach);
    return 1;
}

int sdf__region_build(const sdf__features *s, size_t f, sdf__region *r)
{
    int ok = f < s->faces             ? face_region(s, f, r)
             : f < s->faces + s->edges ? edge_region(s, f - s->faces, r)
                                       : vertex_region(s, f - s->faces - s->edges, r);
    return ok;
}

void sdf__feature_prefetch(const sdf__features *s, size_t f, int stage)
{
    if (f < s->faces) {
        const uint32_t *tri = s->triangles + 3 * f;
        if (!stage)
            __builtin_prefetch(tri);
        else
            for (int c = 0; c < 3; c++)
                __builtin_prefetch(vertex(s, tri[c]));
    } else if (f < s->faces + s->edges) {
        size_t e = f - s->faces;
        if (!stage) {
            __builtin_prefetch(s->edge_end + 2 * e);
            __builtin_prefetch(s->edge_first + e);
            __builtin_prefetch(s->edge_normal + 3 * e);
        } else {
            __builtin_prefetch(vertex(s, s->edge_end[2 * e]));
            __builtin_prefetch(vertex(s, s->edge_end[2 * e + 1]));
            __builtin_prefetch(s->edge_tri + s->edge_first[e]);
        }
    } else {
        size_t v = f - s->faces - s->edges;
        if (!stage) {
            __builtin_prefetch(vertex(s, (uint32_t)v));
            __builtin_prefetch(s->vert_first + v);
            __builtin_prefetch(s->vertex_normal + 3 * v);
        } else {
            __builtin_prefetch(s->vert_nbr + s->vert_first[v]);
        }
    }
}

/* ---- reach and bound ---------------------------------------------------------------------- */

int sdf__features_bound(sdf__features *f, const sdf_mesh *mesh, const double *const coord[3],
                        const size_t dims[3], size_t step, int threads, float **bound,
                        double *bound_coord[3])
{
    size_t n[3], count = 1;
    double half_diag2 = 0, finest = INFINITY;
    for (int a = 0; a < 3; a++) {
        n[a] = sdf__features_bound_nodes(dims[a], step);
        count *= n[a];
    }
    /* One block: the distances, then the closest points. */
    float *pts = calloc(count * 3, sizeof *pts), *d = malloc(count * 4 * sizeof *d);
    *bound = d;
    for (int a = 0; a < 3; a++) {
        bound_coord[a] = malloc(n[a] * sizeof(double));
        double gap = 0;
        for (size_t i = 0; bound_coord[a] && i < n[a]; i++) {
            bound_coord[a][i] = coord[a][i * step < dims[a] ? i * step : dims[a] - 1];
            if (i > 0)
                gap = sdf__max2(gap, bound_coord[a][i] - bound_coord[a][i - 1]);
        }
        half_diag2 += 0.25 * gap * gap;
        finest = sdf__min2(finest, (coord[a][dims[a] - 1] - coord[a][0]) / (double)(dims[a] - 1));
        f->bound_inv_step[a] = (double)(n[a] - 1) / (coord[a][dims[a] - 1] - coord[a][0]);
    }
    if (!pts || !d || !bound_coord[0] || !bound_coord[1] || !bound_coord[2]) {
        free(pts);
        return SDF_ENOMEM;
    }
    size_t q = 0;
    for (size_t k = 0; k < n[2]; k++)
        for (size_t j = 0; j < n[1]; j++)
            for (size_t i = 0; i < n[0]; i++, q++) {
                size_t idx[3] = {i, j, k};
                for (int a = 0; a < 3; a++)
                    pts[3 * q + a] = (float)bound_coord[a][idx[a]];
            }
    int sided = mesh->report.auto_sign == SDF_SIGN_PSEUDONORMAL;
    sdf_query_options o = {.sign = sided ? SDF_SIGN_PSEUDONORMAL : SDF_SIGN_NONE,
                           .threads = threads};
    sdf_query_result res = {.distance = d, .closest = d + count};
    int rc = sdf__query_points(mesh, pts, count, &o, &res);
    double outside = 0, inside = 0, far = 0;
    for (size_t p = 0; !rc && p < count; p++) {
        outside = sdf__max2(outside, d[p]);
        inside = sdf__max2(inside, -d[p]);
        d[p] = fabsf(d[p]);
    }
    for (size_t c = 0; !rc && c < 3 * count; c++)
        far = sdf__max2(far, fabsf(d[count + c]));
    f->bound = d;
    f->bound_point = d + count;
    /* Each coordinate rounded to float: within half an ulp of the exact closest point. */
    f->bound_point_error = 2 * FLT_EPSILON * far;
    for (int a = 0; a < 3; a++)
        f->bound_dims[a] = n[a], f->bound_coord[a] = bound_coord[a];
    /* Any surface point gives a valid cut (a later one only scans more), so the march need
     * not be fine: a whole coarse cell a step costs fewer cuts than half a cell and loses
     * little of their tightness. */
    f->march = (double)step * finest;
    /* Widened past the float rounding of the coarse distances. */
    double widen = sqrt(half_diag2) * (1 + 1e-6) + f->slack;
    f->reach_front = (sided ? outside : sdf__max2(outside, inside)) * (1 + 1e-6) + widen;
    f->reach_back = (sided ? inside : sdf__max2(outside, inside)) * (1 + 1e-6) + widen;
    free(pts);
    return rc;
}

/* ---- adjacency --------------------------------------------------------------------------- */

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

/* The two adjacency lists, each a counting sort of its own pairs: built side by side. */
typedef struct csr_job {
    size_t keys, pairs;
    const uint32_t *key, *value;
    uint32_t **first, **list;
    int rc;
} csr_job;

static void csr_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    csr_job *jobs = ctx;
    for (size_t j = begin; j < end; j++)
        jobs[j].rc = csr(jobs[j].keys, jobs[j].pairs, jobs[j].key, jobs[j].value, jobs[j].first,
                         jobs[j].list);
}

int sdf__features_init(sdf__features *s, const sdf_mesh *m, int threads)
{
    memset(s, 0, sizeof *s);
    s->triangles = m->triangles;
    s->edge_normal = m->normals->edge;
    s->vertex_normal = m->normals->vertex;
    s->faces = m->report.triangles;
    s->edges = m->edge_count;
    s->vertices = m->report.vertices;
    s->count = s->faces + s->edges + s->vertices;
    size_t t3 = 3 * s->faces;
    s->pos = malloc((3 * s->vertices + 1) * sizeof *s->pos);
    for (size_t i = 0; s->pos && i < 3 * s->vertices; i++)
        s->pos[i] = m->positions[i];
    /* Pairs: (edge, its triangle) per corner (the mesh's edge ids are the keys);
     * (vertex, neighbour) both ways per edge. */
    uint32_t *corner_tri = malloc((t3 + 1) * sizeof *corner_tri);
    uint32_t *nbr_key = malloc((2 * s->edges + 1) * sizeof *nbr_key);
    uint32_t *nbr_val = malloc((2 * s->edges + 1) * sizeof *nbr_val);
    s->edge_end = malloc((2 * s->edges + 1) * sizeof *s->edge_end);
    s->vertex_tri = malloc((s->vertices + 1) * sizeof *s->vertex_tri);
    int rc = corner_tri && nbr_key && nbr_val && s->edge_end && s->vertex_tri && s->pos
                 ? 0
                 : SDF_ENOMEM;
    if (!rc) {
        for (size_t v = 0; v < s->vertices; v++)
            s->vertex_tri[v] = UINT32_MAX;
        /* Each triangle's edges and their ends; a vertex's first triangle, corners in order,
         * is its lowest-numbered. */
        for (size_t c = 0; c < t3; c++) {
            uint32_t e = m->edge_of[c], t = (uint32_t)(c / 3);
            corner_tri[c] = t;
            uint32_t a = m->triangles[c], b = m->triangles[c - c % 3 + (c % 3 + 1) % 3];
            s->edge_end[2 * e] = a < b ? a : b, s->edge_end[2 * e + 1] = a < b ? b : a;
            if (s->vertex_tri[a] == UINT32_MAX)
                s->vertex_tri[a] = t;
        }
        for (size_t e = 0; e < s->edges; e++) { /* every edge is a neighbour relation both ways */
            nbr_key[2 * e] = s->edge_end[2 * e], nbr_val[2 * e] = s->edge_end[2 * e + 1];
            nbr_key[2 * e + 1] = s->edge_end[2 * e + 1], nbr_val[2 * e + 1] = s->edge_end[2 * e];
        }
        csr_job jobs[2] = {
            {s->edges, t3, m->edge_of, corner_tri, &s->edge_first, &s->edge_tri, 0},
            {s->vertices, 2 * s->edges, nbr_key, nbr_val, &s->vert_first, &s->vert_nbr, 0},
        };
        sdf__parallel_for(2, 1, threads, csr_range, jobs);
        for (int j = 0; j < 2 && !rc; j++)
            rc = jobs[j].rc;
    }
    free(corner_tri), free(nbr_key), free(nbr_val);
    if (rc)
        sdf__features_free(s);
    return rc;
}

void sdf__features_free(sdf__features *s)
{
    free(s->pos), free(s->edge_end), free(s->edge_first), free(s->edge_tri);
    free(s->vert_first), free(s->vert_nbr), free(s->vertex_tri);
    memset(s, 0, sizeof *s);
}

uint32_t sdf__feature_triangle(const sdf__features *s, size_t feature)
{
    return feature < s->faces ? (uint32_t)feature
           : feature < s->faces + s->edges ? s->edge_tri[s->edge_first[feature - s->faces]]
                                           : s->vertex_tri[feature - s->faces - s->edges];
}
