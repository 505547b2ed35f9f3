/* winding.c - hierarchical winding numbers (see winding.h). */
#include "sign/winding.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bvh/tree.h"
#include "core/simd.h"
#include "sdf/sdf.h"

/* Far-field accuracy: a node is approximated when |q - p~| > BETA * r. Barill et al. use 2
 * for their second-order expansion; the sign tests pass with margin at this value. */
#define BETA 2.0

/* Multipole moments of a subtree's triangles t, with area vectors A_t = area_t * n_t and
 * centroids x_t:  N = sum A_t;  M = sum (x_t - p~) A_t^T;  p~ the area-weighted centroid. */
typedef struct moments {
    double center[3];
    double radius;
    double area;
    double normal[3];
    double m[3][3];
} moments;

/* The same, stored compactly: computed in double, kept in float (half the memory; the
 * expansion's own error is far larger than float rounding). */
typedef struct stored_moments {
    float center[3];
    float radius;
    float normal[3];
    float m[3][3];
} stored_moments;

struct sdf__winding {
    const sdf__tree *tree;
    stored_moments *moments;
    const float *positions;
    const uint32_t *triangles;
};

static void corners(const sdf__winding *w, uint32_t tri, double p[3][3])
{
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++)
            p[k][i] = w->positions[3 * w->triangles[3 * (size_t)tri + k] + i];
}

SDF__HOT_INLINE double length(const double v[3])
{
    return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* Moments of a leaf, summed directly over its triangles. */
static void leaf_moments(const sdf__winding *w, const sdf__tree_node *node, moments *mo)
{
    memset(mo, 0, sizeof *mo);
    double centroid_sum[3] = {0, 0, 0};
    for (uint32_t i = 0; i < node->count; i++) {
        double p[3][3];
        corners(w, w->tree->prims[node->first + i], p);
        double u[3], v[3], a[3];
        for (int k = 0; k < 3; k++) {
            u[k] = p[1][k] - p[0][k];
            v[k] = p[2][k] - p[0][k];
        }
        a[0] = 0.5 * (u[1] * v[2] - u[2] * v[1]);
        a[1] = 0.5 * (u[2] * v[0] - u[0] * v[2]);
        a[2] = 0.5 * (u[0] * v[1] - u[1] * v[0]);
        double area = length(a);
        for (int k = 0; k < 3; k++) {
            double c = (p[0][k] + p[1][k] + p[2][k]) / 3;
            centroid_sum[k] += area > 0 ? area * c : 0;
            mo->normal[k] += a[k];
        }
        mo->area += area;
    }
    /* Centre: area-weighted centroid, or the box centre for an all-degenerate leaf. */
    for (int k = 0; k < 3; k++)
        mo->center[k] = mo->area > 0 ? centroid_sum[k] / mo->area
                                     : 0.5 * ((double)node->lo[k] + node->hi[k]);
    for (uint32_t i = 0; i < node->count; i++) {
        double p[3][3];
        corners(w, w->tree->prims[node->first + i], p);
        double u[3], v[3], a[3], d[3];
        for (int k = 0; k < 3; k++) {
            u[k] = p[1][k] - p[0][k];
            v[k] = p[2][k] - p[0][k];
            d[k] = (p[0][k] + p[1][k] + p[2][k]) / 3 - mo->center[k];
        }
        a[0] = 0.5 * (u[1] * v[2] - u[2] * v[1]);
        a[1] = 0.5 * (u[2] * v[0] - u[0] * v[2]);
        a[2] = 0.5 * (u[0] * v[1] - u[1] * v[0]);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++)
                mo->m[r][c] += d[r] * a[c];
        for (int k = 0; k < 3; k++) {
            double e[3] = {p[k][0] - mo->center[0], p[k][1] - mo->center[1],
                           p[k][2] - mo->center[2]};
            double dist = length(e);
            mo->radius = dist > mo->radius ? dist : mo->radius;
        }
    }
}

/* Moments of an inner node from its children's, re-centred: M = sum (M_c + (p~_c - p~) N_c^T). */
static void merge_moments(const moments *l, const moments *r, moments *mo)
{
    memset(mo, 0, sizeof *mo);
    mo->area = l->area + r->area;
    for (int k = 0; k < 3; k++) {
        mo->normal[k] = l->normal[k] + r->normal[k];
        mo->center[k] = mo->area > 0 ? (l->area * l->center[k] + r->area * r->center[k]) / mo->area
                                     : 0.5 * (l->center[k] + r->center[k]);
    }
    const moments *child[2] = {l, r};
    for (int ci = 0; ci < 2; ci++) {
        const moments *c = child[ci];
        double shift[3] = {c->center[0] - mo->center[0], c->center[1] - mo->center[1],
                           c->center[2] - mo->center[2]};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                mo->m[a][b] += c->m[a][b] + shift[a] * c->normal[b];
        double reach = length(shift) + c->radius;
        mo->radius = reach > mo->radius ? reach : mo->radius;
    }
}

int sdf__winding_create(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                        sdf__winding **out)
{
    sdf__winding *w = calloc(1, sizeof *w);
    moments *full = malloc((tree->node_count + 1) * sizeof *full); /* build-time, double */
    if (w)
        w->moments = malloc(tree->node_count * sizeof *w->moments);
    if (!w || !w->moments || !full) {
        free(full);
        sdf__winding_destroy(w);
        return SDF_ENOMEM;
    }
    w->tree = tree;
    w->positions = positions;
    w->triangles = triangles;
    /* Children follow their parent in the array: a reverse sweep sees them first. */
    for (size_t i = w->tree->node_count; i-- > 0;) {
        const sdf__tree_node *node = &w->tree->nodes[i];
        if (node->count)
            leaf_moments(w, node, &full[i]);
        else
            merge_moments(&full[node->first], &full[node->first + 1], &full[i]);
    }
    for (size_t i = 0; i < w->tree->node_count; i++) {
        stored_moments *s = &w->moments[i];
        for (int a = 0; a < 3; a++) {
            s->center[a] = (float)full[i].center[a];
            s->normal[a] = (float)full[i].normal[a];
            for (int b = 0; b < 3; b++)
                s->m[a][b] = (float)full[i].m[a][b];
        }
        /* Round the radius up: a far-field decision must never be taken too early. */
        s->radius = nextafterf((float)full[i].radius, INFINITY);
    }
    free(full);
    *out = w;
    return 0;
}

void sdf__winding_destroy(sdf__winding *w)
{
    if (!w)
        return;
    free(w->moments);
    free(w);
}

size_t sdf__winding_build_bytes(size_t node_count)
{
    return sizeof(sdf__winding) + node_count * sizeof(stored_moments) +
           (node_count + 1) * sizeof(moments);
}

size_t sdf__winding_bytes(const sdf__winding *w)
{
    return w ? w->tree->node_count * sizeof(stored_moments) : 0;
}

double sdf__solid_angle(const double q[3], const double a[3], const double b[3],
                        const double c[3])
{
    double x[3], y[3], z[3];
    for (int i = 0; i < 3; i++) {
        x[i] = a[i] - q[i];
        y[i] = b[i] - q[i];
        z[i] = c[i] - q[i];
    }
    double lx = length(x), ly = length(y), lz = length(z);
    double det = x[0] * (y[1] * z[2] - y[2] * z[1]) - x[1] * (y[0] * z[2] - y[2] * z[0]) +
                 x[2] * (y[0] * z[1] - y[1] * z[0]);
    double xy = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    double yz = y[0] * z[0] + y[1] * z[1] + y[2] * z[2];
    double zx = z[0] * x[0] + z[1] * x[1] + z[2] * x[2];
    return 2 * atan2(det, lx * ly * lz + xy * lz + yz * lx + zx * ly);
}

/* Solid angle of a far node: integral over its triangles of (x - q).n / |x - q|^3 dA,
 * with f(r) = r/|r|^3 expanded about r0 = p~ - q to first order (J = df/dr):
 *   f(r0) . N  +  trace(J M),   J = I/|r0|^3 - 3 r0 r0^T / |r0|^5. */
SDF__HOT_INLINE double far_field(const stored_moments *mo, const double r[3], double d)
{
    double d3 = d * d * d, d5 = d3 * d * d;
    double first = (r[0] * mo->normal[0] + r[1] * mo->normal[1] + r[2] * mo->normal[2]) / d3;
    double trace = mo->m[0][0] + mo->m[1][1] + mo->m[2][2];
    double rmr = 0;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            rmr += r[a] * mo->m[a][b] * r[b];
    return first + trace / d3 - 3 * rmr / d5;
}

/* One triangle of a near leaf: its exact solid angle when q is close to it, else the first
 * term of the same expansion with the triangle as its own node (centre the centroid, where
 * the second term vanishes): r . A / |r|^3, r = centroid - q, A the area vector. The
 * criterion is the nodes' (|r| > BETA * radius), so the accuracy is theirs, and most of a
 * near leaf's atan2 calls go. */
static double triangle_term(const double q[3], const double p[3][3])
{
    double c[3], r[3], radius2 = 0;
    for (int i = 0; i < 3; i++) {
        c[i] = (p[0][i] + p[1][i] + p[2][i]) / 3;
        r[i] = c[i] - q[i];
    }
    for (int k = 0; k < 3; k++) {
        double e2 = 0;
        for (int i = 0; i < 3; i++)
            e2 += (p[k][i] - c[i]) * (p[k][i] - c[i]);
        radius2 = e2 > radius2 ? e2 : radius2;
    }
    double d2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    if (d2 <= BETA * BETA * radius2)
        return sdf__solid_angle(q, p[0], p[1], p[2]);
    double u[3], v[3];
    for (int i = 0; i < 3; i++) {
        u[i] = p[1][i] - p[0][i];
        v[i] = p[2][i] - p[0][i];
    }
    double a[3] = {0.5 * (u[1] * v[2] - u[2] * v[1]), 0.5 * (u[2] * v[0] - u[0] * v[2]),
                   0.5 * (u[0] * v[1] - u[1] * v[0])};
    double d = sqrt(d2);
    return (r[0] * a[0] + r[1] * a[1] + r[2] * a[2]) / (d2 * d);
}

double sdf__winding_number(const sdf__winding *w, const double q[3])
{
    uint32_t stack[SDF__TREE_MAX_DEPTH + 2];
    int top = 0;
    stack[top++] = 0;
    double omega = 0;
    while (top > 0) {
        uint32_t i = stack[--top];
        const sdf__tree_node *node = &w->tree->nodes[i];
        const stored_moments *mo = &w->moments[i];
        double r[3] = {mo->center[0] - q[0], mo->center[1] - q[1], mo->center[2] - q[2]};
        double d = length(r);
        if (d > BETA * mo->radius) {
            omega += far_field(mo, r, d);
        } else if (node->count) {
            for (uint32_t k = 0; k < node->count; k++) {
                double p[3][3];
                corners(w, w->tree->prims[node->first + k], p);
                omega += triangle_term(q, p);
            }
        } else {
            stack[top++] = node->first;
            stack[top++] = node->first + 1;
        }
    }
    return omega / (4 * M_PI);
}

/* The packet version: one traversal for up to SDF__WINDING_LANES points. Each node carries
 * the mask of lanes for which it is still near; every lane receives exactly the terms, in
 * exactly the order, of sdf__winding_number (the same depth-first order restricted to its
 * mask), so the two agree to the last bit when compiled alike. The far-field terms of all
 * lanes are computed together in straight-line double loops the compiler vectorizes; lanes
 * outside the mask add 0. */
SDF__SIMD_CLONES
void sdf__winding_packet(const sdf__winding *w, const double *qx, const double *qy,
                         const double *qz, int n, double *winding)
{
    typedef uint64_t lane_mask;
    double omega[SDF__WINDING_LANES];
    for (int i = 0; i < SDF__WINDING_LANES; i++)
        omega[i] = 0;
    struct { uint32_t node; lane_mask lanes; } stack[SDF__TREE_MAX_DEPTH + 2];
    int top = 0;
    stack[top].node = 0;
    stack[top++].lanes = n >= 64 ? ~(lane_mask)0 : (((lane_mask)1 << n) - 1);
    while (top > 0) {
        uint32_t index = stack[--top].node;
        lane_mask lanes = stack[top].lanes;
        const sdf__tree_node *node = &w->tree->nodes[index];
        const stored_moments *mo = &w->moments[index];
        double far_term[SDF__WINDING_LANES];
        int far[SDF__WINDING_LANES];
        for (int i = 0; i < SDF__WINDING_LANES; i++) {
            double r[3] = {mo->center[0] - qx[i], mo->center[1] - qy[i], mo->center[2] - qz[i]};
            double d = length(r);
            far[i] = d > BETA * mo->radius;
            far_term[i] = far[i] ? far_field(mo, r, d) : 0.0;
        }
        lane_mask near = 0;
        for (int i = 0; i < n; i++) {
            if (!(lanes >> i & 1))
                continue;
            if (far[i])
                omega[i] += far_term[i];
            else
                near |= (lane_mask)1 << i;
        }
        if (!near)
            continue;
        if (node->count) {
            for (uint32_t k = 0; k < node->count; k++) {
                double p[3][3];
                corners(w, w->tree->prims[node->first + k], p);
                for (int i = 0; i < n; i++) {
                    if (near >> i & 1) {
                        double q[3] = {qx[i], qy[i], qz[i]};
                        omega[i] += triangle_term(q, p);
                    }
                }
            }
        } else {
            stack[top].node = node->first, stack[top++].lanes = near;
            stack[top].node = node->first + 1, stack[top++].lanes = near;
        }
    }
    for (int i = 0; i < n; i++)
        winding[i] = omega[i] / (4 * M_PI);
}
