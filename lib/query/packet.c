/* packet.c - Morton order and packet traversal (see packet.h). */
#include "query/packet.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "query/triangle.h"
#include "sdf/sdf.h"

/* ---- Morton order ------------------------------------------------------------------------ */

/* Spread the low 10 bits of v so they occupy every third bit. */
static uint32_t spread10(uint32_t v)
{
    v &= 0x3ff;
    v = (v | v << 16) & 0x030000ff;
    v = (v | v << 8) & 0x0300f00f;
    v = (v | v << 4) & 0x030c30c3;
    v = (v | v << 2) & 0x09249249;
    return v;
}

int sdf__morton_order(const char *points, size_t stride, size_t count, uint32_t *order)
{
    if (count > UINT32_MAX)
        return SDF_ENOMEM;
    uint64_t *keys = malloc(2 * (count + 1) * sizeof *keys);
    if (!keys)
        return SDF_ENOMEM;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < count; i++) {
        const float *p = (const float *)(points + i * stride);
        for (int k = 0; k < 3; k++) {
            lo[k] = p[k] < lo[k] ? p[k] : lo[k];
            hi[k] = p[k] > hi[k] ? p[k] : hi[k];
        }
    }
    float scale[3];
    for (int k = 0; k < 3; k++)
        scale[k] = hi[k] > lo[k] ? 1023.0f / (hi[k] - lo[k]) : 0.0f;
    /* key = code << 32 | index: sorting keys sorts indices by code, stably. */
    for (size_t i = 0; i < count; i++) {
        const float *p = (const float *)(points + i * stride);
        uint32_t c[3];
        for (int k = 0; k < 3; k++)
            c[k] = (uint32_t)((p[k] - lo[k]) * scale[k]);
        uint64_t code = spread10(c[0]) | spread10(c[1]) << 1 | spread10(c[2]) << 2;
        keys[i] = code << 32 | i;
    }
    uint64_t *src = keys, *dst = keys + count;
    for (int shift = 32; shift < 62; shift += 10) { /* 3 passes of 10 bits over the code */
        size_t hist[1024] = {0};
        for (size_t i = 0; i < count; i++)
            hist[(src[i] >> shift) & 1023]++;
        for (size_t b = 0, sum = 0; b < 1024; b++) {
            size_t h = hist[b];
            hist[b] = sum;
            sum += h;
        }
        for (size_t i = 0; i < count; i++)
            dst[hist[(src[i] >> shift) & 1023]++] = src[i];
        uint64_t *t = src;
        src = dst;
        dst = t;
    }
    for (size_t i = 0; i < count; i++)
        order[i] = (uint32_t)src[i];
    free(keys);
    return 0;
}

/* ---- packet traversal -------------------------------------------------------------------- */

/* Float box tests may round a distance up by a few ulps; culling compares against a bound
 * grown by this factor so rounding can never cull the node or triangle that holds the
 * true closest point. The exact test decides everything else. */
#define CULL_SLACK 1.00001f

/* max/min of finite floats as plain comparisons, which compile to maxss/minss (and vector
 * max/min in loops): fmaxf's NaN rules stop the compiler from inlining it (it became a libm
 * call per box test). Our inputs are never NaN. */
static inline float minf(float a, float b) { return a < b ? a : b; }
static inline float maxf(float a, float b) { return a > b ? a : b; }
static inline float max0(float a, float b) { return maxf(maxf(a, b), 0.0f); }

/* Squared distance from (x, y, z) to the box [lo, hi]; 0 inside. */
static inline float box_dist2(const float lo[3], const float hi[3], float x, float y, float z)
{
    float dx = max0(lo[0] - x, x - hi[0]);
    float dy = max0(lo[1] - y, y - hi[1]);
    float dz = max0(lo[2] - z, z - hi[2]);
    return dx * dx + dy * dy + dz * dz;
}

typedef struct box {
    float lo[3], hi[3];
} box;

/* The packet's points whose distance to the box [lo, hi] is within their culling limit:
 * their indices go to `act`; returns how many. */
static int near_points(const sdf__packet *pk, const float *limit, const float lo[3],
                       const float hi[3], uint8_t *act)
{
    float d2[SDF__PACKET];
    for (int i = 0; i < SDF__PACKET; i++) /* all lanes (padded): SoA, no branches, vectorized */
        d2[i] = box_dist2(lo, hi, pk->x[i], pk->y[i], pk->z[i]);
    int n = 0;
    for (int i = 0; i < pk->n; i++)
        if (d2[i] <= limit[i])
            act[n++] = (uint8_t)i;
    return n;
}

static void triangle_box(const float *positions, const uint32_t *t, double v[3][3], box *b)
{
    for (int k = 0; k < 3; k++) {
        const float *p = positions + 3 * (size_t)t[k];
        for (int a = 0; a < 3; a++) {
            v[k][a] = p[a];
            b->lo[a] = k ? minf(b->lo[a], p[a]) : p[a];
            b->hi[a] = k ? maxf(b->hi[a], p[a]) : p[a];
        }
    }
}

static void visit_leaf(const sdf__tree *tree, const sdf__tree_node *node, const float *positions,
                       const uint32_t *triangles, sdf__packet *pk, float *limit, const uint8_t *act,
                       int nact, sdf__hit *hits)
{
    for (uint32_t k = 0; k < node->count; k++) {
        uint32_t tri = tree->prims[node->first + k];
        double v[3][3];
        box b;
        triangle_box(positions, triangles + 3 * (size_t)tri, v, &b);
        for (int j = 0; j < nact; j++) { /* only the points still interested in this leaf */
            int i = act[j];
            if (box_dist2(b.lo, b.hi, pk->x[i], pk->y[i], pk->z[i]) > limit[i])
                continue;
            double p[3] = {pk->x[i], pk->y[i], pk->z[i]}, c[3], w[3];
            int feature;
            double d2 = sdf__closest_on_triangle(p, v[0], v[1], v[2], c, w, &feature);
            if (d2 < hits[i].dist2 && d2 <= pk->bound2[i]) {
                sdf__hit *h = &hits[i];
                h->dist2 = d2;
                h->triangle = tri;
                h->feature = feature;
                memcpy(h->point, c, sizeof c);
                memcpy(h->bary, w, sizeof w);
                pk->bound2[i] = d2;
                limit[i] = (float)d2 * CULL_SLACK;
            }
        }
    }
}

void sdf__closest_packet(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                         sdf__packet *pk, sdf__hit *hits)
{
    float limit[SDF__PACKET], cx = 0, cy = 0, cz = 0;
    for (int i = 0; i < pk->n; i++) {
        hits[i].dist2 = INFINITY;
        hits[i].triangle = 0;
        /* A seeded bound is grown a little: it may equal the true distance exactly. */
        if (isfinite(pk->bound2[i]))
            pk->bound2[i] = pk->bound2[i] * 1.000001 + 1e-30;
        limit[i] = isfinite(pk->bound2[i]) ? (float)pk->bound2[i] * CULL_SLACK : INFINITY;
        cx += pk->x[i], cy += pk->y[i], cz += pk->z[i];
    }
    cx /= (float)pk->n, cy /= (float)pk->n, cz /= (float)pk->n;
    uint32_t stack[SDF__TREE_MAX_DEPTH + 2];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const sdf__tree_node *node = &tree->nodes[stack[--top]];
        uint8_t act[SDF__PACKET];
        int nact = near_points(pk, limit, node->lo, node->hi, act);
        if (nact == 0)
            continue;
        if (node->count) {
            visit_leaf(tree, node, positions, triangles, pk, limit, act, nact, hits);
            continue;
        }
        /* Near child last on the stack, so it is visited first and shrinks the bounds. */
        const sdf__tree_node *a = &tree->nodes[node->first], *b = a + 1;
        float da = box_dist2(a->lo, a->hi, cx, cy, cz), db = box_dist2(b->lo, b->hi, cx, cy, cz);
        uint32_t near = da <= db ? node->first : node->first + 1;
        stack[top++] = near == node->first ? node->first + 1 : node->first;
        stack[top++] = near;
    }
}
