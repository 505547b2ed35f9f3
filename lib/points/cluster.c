/* cluster.c - closest triangles of a cluster of nearby points (see cluster.h). */
#include "points/cluster.h"

#include <math.h>
#include <stdlib.h>

#include "core/simd.h"
#include "points/lanes.h"
#include "geom/triangle.h"

/* Every float comparison that must not lose a triangle is widened by lanes.h's slack. */
#define SLACK_REL SDF__LANE_SLACK_REL

/* A float distance is taken only above this many slack_abs (relative error <~ 1/64 at worst,
 * far less in practice); nearer points are rare and get the exact test. */
#define FLOAT_DISTANCE_MIN 64.0f

#define BUCKETS 32 /* reach classes of the candidates' visit order */

/* A candidate: its box (the walk's test, and the cheap per-lane test), and the full float
 * test's data, filled in only when some group needs it. */
typedef struct candidate {
    float lo[3], hi[3];
    uint32_t id;
    int prepared;
} candidate;

struct sdf__cluster {
    int capacity;
    candidate *cand;
    sdf__float_triangle *tri; /* tri[i]: candidate i prepared for the lane test */
    float *reach;             /* a lower bound of each candidate's distance from the centre */
    int *order;               /* candidates by bucket of increasing reach */
    float *order_reach;       /* order[t]'s bucket floor: no candidate from t on is nearer */
};

sdf__cluster *sdf__cluster_create(int capacity)
{
    sdf__cluster *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    c->capacity = capacity;
    c->cand = malloc(((size_t)capacity + 1) * sizeof *c->cand); /* + the one that overflows */
    c->tri = malloc((size_t)capacity * sizeof *c->tri);
    c->reach = malloc((size_t)capacity * sizeof *c->reach);
    c->order = malloc((size_t)capacity * sizeof *c->order);
    c->order_reach = malloc((size_t)capacity * sizeof *c->order_reach);
    if (!c->cand || !c->tri || !c->reach || !c->order || !c->order_reach) {
        sdf__cluster_destroy(c);
        return NULL;
    }
    return c;
}

size_t sdf__cluster_bytes(int capacity)
{
    size_t n = (size_t)capacity;
    return sizeof(sdf__cluster) + (n + 1) * sizeof(candidate) +
           n * (sizeof(sdf__float_triangle) + 2 * sizeof(float) + sizeof(int));
}

void sdf__cluster_destroy(sdf__cluster *c)
{
    if (!c)
        return;
    free(c->cand), free(c->tri), free(c->reach), free(c->order), free(c->order_reach);
    free(c);
}

/* Every triangle whose box lies within `radius` of `centre` (in a leaf whose cylinder does),
 * in c's arrays with the box's distance as its reach. Returns their count, or -1 when there
 * are more than the capacity. */
SDF__HOT_INLINE int gather(sdf__cluster *c, const sdf__tree *tree, const float *positions,
                           const uint32_t *triangles, const float centre[3], float radius)
{
    float r2 = radius * radius;
    const float x = centre[0], y = centre[1], z = centre[2];
    int count = 0;
    uint32_t stack[SDF__TREE_MAX_DEPTH + 2];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const sdf__tree_node *node = &tree->nodes[stack[--top]];
        if (sdf__box_dist2f(node->lo, node->hi, x, y, z) > r2)
            continue;
        if (!node->count) {
            stack[top++] = node->first + 1;
            stack[top++] = node->first;
            continue;
        }
        if (sdf__disc_dist2f(&tree->discs[node - tree->nodes], x, y, z) > r2)
            continue; /* the leaf's cylinder (bvh/tree.h) is farther than its box */
        for (uint32_t k = 0; k < node->count; k++) {
            uint32_t tri = tree->prims[node->first + k];
            const float *v[3];
            for (int i = 0; i < 3; i++)
                v[i] = positions + 3 * (size_t)triangles[3 * (size_t)tri + i];
            candidate *cd = &c->cand[count];
            for (int a = 0; a < 3; a++) {
                cd->lo[a] = sdf__minf(sdf__minf(v[0][a], v[1][a]), v[2][a]);
                cd->hi[a] = sdf__maxf(sdf__maxf(v[0][a], v[1][a]), v[2][a]);
            }
            float d2 = sdf__box_dist2f(cd->lo, cd->hi, x, y, z);
            if (d2 > r2)
                continue;
            if (count == c->capacity)
                return -1;
            cd->id = tri;
            cd->prepared = 0;
            c->reach[count++] = sqrtf(d2);
        }
    }
    return count;
}

static int bucket_of(float reach, float low, float scale)
{
    int b = (int)((reach - low) * scale);
    return b < BUCKETS - 1 ? b : BUCKETS - 1;
}

/* c->order[0..count): the candidates by bucket of reach (a counting sort), and for each the
 * floor of its bucket, which no later candidate's reach is below. */
static void sort_by_reach(sdf__cluster *c, int count)
{
    float low = INFINITY, high = 0;
    for (int i = 0; i < count; i++)
        low = sdf__minf(low, c->reach[i]), high = sdf__maxf(high, c->reach[i]);
    float scale = high > low ? (BUCKETS - 1) / (high - low) : 0;
    int start[BUCKETS + 1] = {0};
    for (int i = 0; i < count; i++)
        start[bucket_of(c->reach[i], low, scale) + 1]++;
    for (int b = 0; b < BUCKETS; b++)
        start[b + 1] += start[b];
    for (int i = 0; i < count; i++) {
        int b = bucket_of(c->reach[i], low, scale), at = start[b]++;
        c->order[at] = i;
        c->order_reach[at] = scale > 0 ? low + (float)b / scale : low;
    }
}

/* Candidate j prepared for the full test. */
SDF__HOT_INLINE const sdf__float_triangle *prepared(sdf__cluster *c, int j, const float *positions,
                                                   const uint32_t *triangles)
{
    sdf__float_triangle *f = &c->tri[j];
    if (!c->cand[j].prepared) {
        const uint32_t *t = triangles + 3 * (size_t)c->cand[j].id;
        for (int v = 0; v < 3; v++)
            for (int a = 0; a < 3; a++)
                f->v[v][a] = positions[3 * (size_t)t[v] + a];
        sdf__float_triangle_prepare(f);
        c->cand[j].prepared = 1;
    }
    return f;
}

/* clang checks the vector ABI of each call in a function compiled for AVX before it inlines
 * anything, and rejects a 32-byte vector passed to a helper compiled without AVX: under
 * clang the entry point compiled twice (core/simd.h) passes only pointers and scalars to
 * this body, inlined into each clone. GCC checks after inlining, so there the body is
 * the entry point itself (a wrapper would move its stack slots). */
#if defined(__clang__)
SDF__HOT_INLINE int cluster_closest(sdf__cluster *c, const sdf__tree *tree,
                                    const float *positions, const uint32_t *triangles,
                                    float extent, const char *points, size_t stride,
                                    const double *bound, const uint8_t *want, int n,
                                    sdf__hit *hits)
#else
SDF__SIMD_CLONES
int sdf__cluster_closest(sdf__cluster *c, const sdf__tree *tree, const float *positions,
                         const uint32_t *triangles, float extent, const char *points,
                         size_t stride, const double *bound, const uint8_t *want, int n,
                         sdf__hit *hits)
#endif
{
    const float slack_abs = SDF__LANE_SLACK_ABS_OF_EXTENT * extent;
    const float exact_below2 = (FLOAT_DISTANCE_MIN * slack_abs) * (FLOAT_DISTANCE_MIN * slack_abs);
    /* SoA lanes, padded to whole groups with copies of the last point. */
    float x[SDF__CLUSTER_MAX], y[SDF__CLUSTER_MAX], z[SDF__CLUSTER_MAX], off[SDF__CLUSTER_MAX];
    int groups = (n + SDF__LANE_GROUP - 1) / SDF__LANE_GROUP;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < groups * SDF__LANE_GROUP; i++) {
        const float *p = (const float *)(points + (size_t)(i < n ? i : n - 1) * stride);
        x[i] = p[0], y[i] = p[1], z[i] = p[2];
        for (int a = 0; a < 3; a++)
            lo[a] = sdf__minf(lo[a], p[a]), hi[a] = sdf__maxf(hi[a], p[a]);
    }
    float centre[3];
    for (int a = 0; a < 3; a++)
        centre[a] = 0.5f * (lo[a] + hi[a]);
    /* A point's closest triangle lies within bound + |x - c| of the centre c. */
    double radius = 0;
    for (int i = 0; i < groups * SDF__LANE_GROUP; i++) {
        double dx = x[i] - centre[0], dy = y[i] - centre[1], dz = z[i] - centre[2];
        double gap = sqrt(dx * dx + dy * dy + dz * dz);
        off[i] = (float)gap * (1 + SLACK_REL) + slack_abs;
        radius = fmax(radius, bound[i < n ? i : n - 1] + gap);
    }
    int count = gather(c, tree, positions, triangles, centre,
                       (float)radius * (1 + SLACK_REL) + slack_abs);
    if (count < 0)
        return -1;
    sort_by_reach(c, count);
    for (int g = 0; g < groups; g++) {
        const int base = g * SDF__LANE_GROUP;
        const sdf__v8f gx = sdf__v8f_load(x + base), gy = sdf__v8f_load(y + base),
                       gz = sdf__v8f_load(z + base), goff = sdf__v8f_load(off + base);
        sdf__v8f best2 = sdf__v8f_splat(INFINITY);
        sdf__v8i win = (sdf__v8i){0} - 1;
        for (int t = 0; t < count; t++) {
            /* No candidate from here on is nearer to x than reach - |x - c|: once that passes
             * every lane's best, the group is done. */
            sdf__v8f lower = (c->order_reach[t] * (1 - SLACK_REL) - slack_abs) - goff;
            if (!sdf__v8i_any((lower <= 0) | (lower * lower < best2)))
                break;
            int j = c->order[t];
            const candidate *cd = &c->cand[j];
            /* The box test first: most candidates fail it in every lane. */
            if (!sdf__v8i_any(sdf__box_dist2_lanes(cd->lo, cd->hi, gx, gy, gz) < best2))
                continue;
            sdf__v8f d2 = sdf__triangle_lanes(prepared(c, j, positions, triangles), gx, gy, gz);
            sdf__v8i nearer = d2 < best2;
            best2 = sdf__v8f_select(nearer, d2, best2);
            win = (nearer & j) | (~nearer & win);
        }
        for (int i = 0; i < SDF__LANE_GROUP && base + i < n; i++) {
            sdf__hit *h = &hits[base + i];
            h->dist2 = INFINITY;
            h->triangle = 0;
            if (win[i] < 0)
                continue;
            /* Float distances err by up to ~slack_abs: near the surface that is large next to
             * the distance itself, so there the exact test decides. */
            int w = want && best2[i] > exact_below2 ? want[base + i] : SDF__CLUSTER_EXACT;
            uint32_t tri = c->cand[win[i]].id;
            if (w != SDF__CLUSTER_FLOAT) {
                double p[3] = {x[base + i], y[base + i], z[base + i]};
                sdf__triangle_offer(positions, triangles, tri, p, h);
            }
            if (w != SDF__CLUSTER_EXACT) {
                h->dist2 = best2[i];
                h->triangle = tri;
            }
        }
    }
    return 0;
}

#if defined(__clang__)
SDF__SIMD_CLONES
int sdf__cluster_closest(sdf__cluster *c, const sdf__tree *tree, const float *positions,
                         const uint32_t *triangles, float extent, const char *points,
                         size_t stride, const double *bound, const uint8_t *want, int n,
                         sdf__hit *hits)
{
    return cluster_closest(c, tree, positions, triangles, extent, points, stride, bound, want, n,
                           hits);
}
#endif
