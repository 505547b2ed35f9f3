/* packet.c - packet traversal and the single-point walk (see packet.h).
 *
 * The float tests here only choose candidates, within margins ~16x their rounding, and the
 * exact double test (geom/triangle.c, another file) decides every answer, so their
 * multiply-adds may fuse where the CPU has FMA: the answers stay bit for bit the same, and
 * the walks take fewer instructions. The rest of the library keeps ISO C's unfused
 * arithmetic, so its floats do not depend on the CPU. Each compiler names the switch its own
 * way. */
#if defined(__clang__)
#pragma clang fp contract(fast)
#else
#pragma GCC optimize("fp-contract=fast")
#endif
#include "points/packet.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bvh/wide.h"
#include "core/simd.h"
#include "points/lanes.h"
#include "geom/triangle.h"
#include "sdf/sdf.h"

/* ---- packet traversal -------------------------------------------------------------------- */

/* Float box tests may round a distance up by a few ulps; culling compares against a bound
 * grown by this factor so rounding can never cull the node that holds the true closest
 * point. */
#define CULL_SLACK 1.00001f

/* Every triangle whose float distance is within TIE_REL * d + TIE_ABS of a lane's best float
 * distance is a candidate, and the candidates get the exact double test. The margins are the
 * float test's slack (lanes.h) and cost nothing measurable: near ties are rare except at
 * shared vertices and edges, which the exact test must see anyway. */
#define TIE_REL SDF__LANE_SLACK_REL
#define TIE_ABS_OF_EXTENT SDF__LANE_SLACK_ABS_OF_EXTENT

/* Lanes are handled in groups of LANE_GROUP (one AVX vector of floats): a triangle gets the
 * full float test only in the groups that have a lane near its box. */
#define LANE_GROUP SDF__LANE_GROUP
#define LANE_GROUPS (SDF__PACKET / LANE_GROUP)
_Static_assert(SDF__PACKET % LANE_GROUP == 0, "a packet is whole groups");

/* Bit i set: lane i lies within its limit of leaf cylinder c (only groups in `groups` are
 * looked at). */
SDF__HOT_INLINE uint32_t lanes_near_disc(const sdf__packet *pk, const float *limit2,
                                         const sdf__tree_disc *c, unsigned groups)
{
    _Static_assert(SDF__PACKET <= 32, "a lane mask is 32 bits");
    sdf__v8i bits = (sdf__v8i){0};
    for (int g = 0; g < LANE_GROUPS; g++) {
        if (!(groups >> g & 1))
            continue;
        const int o = g * LANE_GROUP;
        sdf__v8f d2 = sdf__disc_dist2_lanes(c, sdf__v8f_load(pk->x + o), sdf__v8f_load(pk->y + o),
                                            sdf__v8f_load(pk->z + o));
        bits |= (d2 <= sdf__v8f_load(limit2 + o)) &
                ((sdf__v8i){1, 2, 4, 8, 16, 32, 64, 128} << (g * LANE_GROUP));
    }
    return sdf__v8i_or_lanes(bits);
}

/* Bit g set: lane mask `lanes` has a lane in group g. */
static inline unsigned groups_of_lanes(uint32_t lanes)
{
    unsigned groups = 0;
    for (int g = 0; g < LANE_GROUPS; g++)
        groups |= (lanes >> (g * LANE_GROUP) & 0xffu) ? 1u << g : 0;
    return groups;
}

/* Bit g set: some lane of group g lies within its limit of the box [lo, hi]. */
SDF__HOT_INLINE unsigned groups_near_box(const sdf__packet *pk, const float *limit2,
                                         const float lo[3], const float hi[3])
{
    sdf__v8i bits = (sdf__v8i){0};
    for (int g = 0; g < LANE_GROUPS; g++) {
        const int o = g * LANE_GROUP;
        sdf__v8f d2 = sdf__box_dist2_lanes(lo, hi, sdf__v8f_load(pk->x + o),
                                           sdf__v8f_load(pk->y + o), sdf__v8f_load(pk->z + o));
        bits |= (d2 <= sdf__v8f_load(limit2 + o)) & (1 << g);
    }
    return sdf__v8i_or_lanes(bits);
}

/* Each lane's candidates: the triangles whose float distance was within the tie margin of
 * the lane's best float distance when they were seen. */
#define MAX_CANDIDATES 16

typedef struct lane_state {
    float best;   /* best float distance so far (INFINITY: none) */
    int count;    /* candidates held; MAX_CANDIDATES + 1 once they overflowed */
    uint32_t tri[MAX_CANDIDATES];
    float dist2[MAX_CANDIDATES];
} lane_state;

/* Lane i saw triangle `tri` at float squared distance d2 (already within its limit). */
SDF__HOT_INLINE void lane_offer(lane_state *s, float *limit2, float tie_abs, uint32_t tri, float d2)
{
    if (d2 < s->best * s->best) {
        s->best = sqrtf(d2);
        float lim = s->best * (1 + TIE_REL) + tie_abs;
        *limit2 = sdf__minf(*limit2, lim * lim);
        int kept = 0; /* drop the candidates the new best put out of reach */
        for (int c = 0; c < s->count && c < MAX_CANDIDATES; c++) {
            if (s->dist2[c] <= *limit2) {
                s->tri[kept] = s->tri[c];
                s->dist2[kept++] = s->dist2[c];
            }
        }
        s->count = s->count > MAX_CANDIDATES ? s->count : kept;
    }
    if (s->count < MAX_CANDIDATES) {
        s->tri[s->count] = tri;
        s->dist2[s->count++] = d2;
    } else {
        s->count = MAX_CANDIDATES + 1;
    }
}

SDF__HOT_INLINE void visit_leaf(const sdf__tree *tree, const sdf__tree_node *node,
                                const float *positions, const uint32_t *triangles,
                                const sdf__packet *pk, unsigned groups, float *limit2,
                                float tie_abs, lane_state *lanes)
{
    for (uint32_t k = 0; k < node->count; k++) {
        uint32_t tri = tree->prims[node->first + k];
        const uint32_t *t = triangles + 3 * (size_t)tri;
        float v[3][3]; /* corners loaded once: for the box test, then for the lane test */
        for (int c = 0; c < 3; c++)
            memcpy(v[c], positions + 3 * (size_t)t[c], 3 * sizeof(float));
        float lo[3], hi[3];
        for (int a = 0; a < 3; a++) {
            lo[a] = sdf__minf(sdf__minf(v[0][a], v[1][a]), v[2][a]);
            hi[a] = sdf__maxf(sdf__maxf(v[0][a], v[1][a]), v[2][a]);
        }
        unsigned near = groups & groups_near_box(pk, limit2, lo, hi);
        if (!near)
            continue;
        sdf__triangle8 f; /* the one triangle in every lane */
        for (int c = 0; c < 3; c++)
            for (int a = 0; a < 3; a++)
                f.v[c][a] = sdf__v8f_splat(v[c][a]);
        sdf__triangle8_prepare(&f);
        /* Every near group's distances first, then the lanes that passed, one bit each, so
         * only those are visited (lanes that pass are rare); a lane's offer changes only its
         * own limit. */
        sdf__v8f dist2[LANE_GROUPS];
        sdf__v8i bits = (sdf__v8i){0};
        for (int g = 0; g < LANE_GROUPS; g++) {
            if (!(near >> g & 1))
                continue;
            const int o = g * LANE_GROUP;
            sdf__v8f px = sdf__v8f_load(pk->x + o), py = sdf__v8f_load(pk->y + o),
                     pz = sdf__v8f_load(pk->z + o);
            dist2[g] = sdf__triangle8_dist2(&f, px, py, pz);
            bits |= (dist2[g] <= sdf__v8f_load(limit2 + o)) &
                    ((sdf__v8i){1, 2, 4, 8, 16, 32, 64, 128} << (g * LANE_GROUP));
        }
        for (uint32_t pass = sdf__v8i_or_lanes(bits); pass; pass &= pass - 1) {
            const int i = __builtin_ctz(pass);
            lane_offer(&lanes[i], &limit2[i], tie_abs, tri, dist2[i / LANE_GROUP][i % LANE_GROUP]);
        }
    }
}

/* Up to eight of a leaf's triangles, one per lane: prims[first + k0 ..], n of them; short
 * chunks repeat their first triangle in the spare lanes, which are never offered. */
typedef struct leaf_chunk {
    sdf__triangle8 f;
    uint32_t ids[LANE_GROUP];
    int n;
} leaf_chunk;

SDF__HOT_INLINE void leaf_chunk_prepare(const sdf__tree *tree, const sdf__tree_node *node,
                                        uint32_t k0, const float *positions,
                                        const uint32_t *triangles, leaf_chunk *ch)
{
    int n = node->count - k0 < LANE_GROUP ? (int)(node->count - k0) : LANE_GROUP;
    float corner[3][3][LANE_GROUP];
    for (int t = 0; t < LANE_GROUP; t++) {
        ch->ids[t] = tree->prims[node->first + k0 + (uint32_t)(t < n ? t : 0)];
        const uint32_t *tri = triangles + 3 * (size_t)ch->ids[t];
        for (int c = 0; c < 3; c++)
            for (int a = 0; a < 3; a++)
                corner[c][a][t] = positions[3 * (size_t)tri[c] + a];
    }
    for (int c = 0; c < 3; c++)
        for (int a = 0; a < 3; a++)
            ch->f.v[c][a] = sdf__v8f_load(corner[c][a]);
    sdf__triangle8_prepare(&ch->f);
    ch->n = n;
}

/* The chunk's triangles offered to one point's lane state. */
SDF__HOT_INLINE void leaf_chunk_test(const leaf_chunk *ch, sdf__v8f vx, sdf__v8f vy, sdf__v8f vz,
                                     float *limit2, float tie_abs, lane_state *lane)
{
    sdf__v8f dist2 = sdf__triangle8_dist2(&ch->f, vx, vy, vz);
    const sdf__v8i bit = {1, 2, 4, 8, 16, 32, 64, 128};
    unsigned within = sdf__v8i_or_lanes((dist2 <= *limit2) & bit) & ((1u << ch->n) - 1);
    if (within & (within - 1)) { /* several: the nearest first, so the limit shrinks first */
        int nearest = __builtin_ctz(within);
        for (unsigned m = within & (within - 1); m; m &= m - 1)
            nearest = dist2[__builtin_ctz(m)] < dist2[nearest] ? __builtin_ctz(m) : nearest;
        lane_offer(lane, limit2, tie_abs, ch->ids[nearest], dist2[nearest]);
        within &= ~(1u << nearest);
    }
    /* Only the triangles that passed, each against the limit the ones before it left. */
    for (; within; within &= within - 1) {
        const int t = __builtin_ctz(within);
        if (dist2[t] <= *limit2)
            lane_offer(lane, limit2, tie_abs, ch->ids[t], dist2[t]);
    }
}

/* The leaf's triangles eight at a time against one point (the single-point walk). */
SDF__HOT_INLINE void point_leaf(const sdf__tree *tree, const sdf__tree_node *node,
                                const float *positions, const uint32_t *triangles, sdf__v8f vx,
                                sdf__v8f vy, sdf__v8f vz, float *limit2, float tie_abs,
                                lane_state *lane)
{
    for (uint32_t k0 = 0; k0 < node->count; k0 += LANE_GROUP) {
        leaf_chunk ch;
        leaf_chunk_prepare(tree, node, k0, positions, triangles, &ch);
        leaf_chunk_test(&ch, vx, vy, vz, limit2, tie_abs, lane);
    }
}

/* A leaf that few of a packet's lanes come near, the other way round: each near lane
 * against eight of its triangles at a time (as the single-point walk does), where the
 * packet's way tests each triangle against whole groups of eight lanes, most of them too
 * far to gain. `near` has bit i set for lane i. */
SDF__HOT_INLINE void visit_leaf_by_lane(const sdf__tree *tree, const sdf__tree_node *node,
                                        const float *positions, const uint32_t *triangles,
                                        const sdf__packet *pk, uint32_t near, float *limit2,
                                        float tie_abs, lane_state *lanes)
{
    for (uint32_t k0 = 0; k0 < node->count; k0 += LANE_GROUP) {
        leaf_chunk ch;
        leaf_chunk_prepare(tree, node, k0, positions, triangles, &ch);
        for (uint32_t m = near; m; m &= m - 1) {
            const int i = __builtin_ctz(m);
            leaf_chunk_test(&ch, sdf__v8f_splat(pk->x[i]), sdf__v8f_splat(pk->y[i]),
                            sdf__v8f_splat(pk->z[i]), &limit2[i], tie_abs, &lanes[i]);
        }
    }
}

/* The exact double test over a lane's candidates within limit2 decides its closest point. */
static void exact_lane(const float *positions, const uint32_t *triangles, const double p[3],
                       const lane_state *s, float limit2, sdf__hit *hit)
{
    hit->dist2 = INFINITY;
    hit->triangle = 0;
    for (int c = 0; c < s->count; c++) {
        if (s->dist2[c] > limit2)
            continue;
        sdf__triangle_offer(positions, triangles, s->tri[c], p, hit);
    }
}

/* The exact decision over a lane's candidates, or INFINITY when they overflowed. */
static void decide_lane(const float *positions, const uint32_t *triangles, const double p[3],
                        const lane_state *s, float tie_abs, sdf__hit *hit)
{
    if (s->count > MAX_CANDIDATES) { /* too many near ties to hold: ask again */
        hit->dist2 = INFINITY;
        return;
    }
    float lim = s->best * (1 + TIE_REL) + tie_abs;
    exact_lane(positions, triangles, p, s, lim * lim, hit);
}

/* The limit a search bounded by bound2 starts from: the bound plus the tie margin (the true
 * closest triangle's float distance is at most its true distance plus the float error). */
static float start_limit2(double bound2, float tie_abs)
{
    if (!(bound2 < INFINITY))
        return INFINITY;
    float lim = (float)sqrt(bound2) * (1 + TIE_REL) + tie_abs;
    return lim * lim * CULL_SLACK;
}

SDF__SIMD_CLONES
void sdf__closest_packet(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                         float extent, sdf__packet *pk, sdf__hit *hits)
{
    float tie_abs = TIE_ABS_OF_EXTENT * extent;
    float limit2[SDF__PACKET], cx = 0, cy = 0, cz = 0;
    lane_state lanes[SDF__PACKET];
    for (int i = 0; i < SDF__PACKET; i++) {
        limit2[i] = i < pk->n ? start_limit2(pk->bound2[i], tie_abs) : -1.0f; /* padding: never */
        lanes[i].best = INFINITY;
        lanes[i].count = 0;
    }
    for (int i = 0; i < pk->n; i++)
        cx += pk->x[i], cy += pk->y[i], cz += pk->z[i];
    cx /= (float)pk->n, cy /= (float)pk->n, cz /= (float)pk->n;
    uint32_t stack[SDF__TREE_MAX_DEPTH + 2];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const sdf__tree_node *node = &tree->nodes[stack[--top]];
        unsigned groups = groups_near_box(pk, limit2, node->lo, node->hi);
        if (!groups)
            continue;
        if (node->count) {
            uint32_t near = lanes_near_disc(pk, limit2, &tree->discs[node - tree->nodes], groups);
            if (!near)
                continue;
            groups = groups_of_lanes(near);
            /* The way with fewer full eight-lane tests: a near lane per chunk of eight
             * triangles, or (at most) a near group per triangle. Sparse packets (far points,
             * small batches, fine meshes) mostly go by lane; weighting either side by 2 or
             * 1/2 moved nothing beyond the noise (docs/performance.md). */
            unsigned by_lane = (unsigned)__builtin_popcount(near) * ((node->count + 7) / 8);
            unsigned by_group = (unsigned)__builtin_popcount(groups) * node->count;
            if (by_lane <= by_group)
                visit_leaf_by_lane(tree, node, positions, triangles, pk, near, limit2, tie_abs,
                                   lanes);
            else
                visit_leaf(tree, node, positions, triangles, pk, groups, limit2, tie_abs, lanes);
            continue;
        }
        /* Near child last on the stack, so it is visited first and shrinks the bounds. */
        const sdf__tree_node *a = &tree->nodes[node->first], *b = a + 1;
        float da = sdf__box_dist2f(a->lo, a->hi, cx, cy, cz);
        float db = sdf__box_dist2f(b->lo, b->hi, cx, cy, cz);
        uint32_t near = da <= db ? node->first : node->first + 1;
        stack[top++] = near == node->first ? node->first + 1 : node->first;
        stack[top++] = near;
    }
    for (int i = 0; i < pk->n; i++) {
        double p[3] = {pk->x[i], pk->y[i], pk->z[i]};
        decide_lane(positions, triangles, p, &lanes[i], tie_abs, &hits[i]);
    }
}

/* Squared distances from (x, y, z) to the boxes of a wide node's eight children. */
SDF__HOT_INLINE sdf__v8f wide_dist2(const sdf__wide_node *w, sdf__v8f x, sdf__v8f y, sdf__v8f z)
{
    const sdf__v8f lo[3] = {sdf__v8f_load(w->lo[0]), sdf__v8f_load(w->lo[1]),
                            sdf__v8f_load(w->lo[2])};
    const sdf__v8f hi[3] = {sdf__v8f_load(w->hi[0]), sdf__v8f_load(w->hi[1]),
                            sdf__v8f_load(w->hi[2])};
    return sdf__box_dist2_v8(lo, hi, x, y, z);
}

/* A wide walk's pending child: its reference (bvh/wide.h) and box distance when pushed. */
typedef struct wide_entry {
    uint32_t ref;
    float dist2;
} wide_entry;

/* clang checks the vector ABI of each call in a function compiled for AVX before it inlines
 * anything, and rejects a 32-byte vector passed to a helper compiled without AVX: under
 * clang the entry point compiled twice (core/simd.h) passes only pointers and scalars to
 * this body, inlined into each clone. GCC checks after inlining, so there the body is
 * the entry point itself (a wrapper would move its stack slots). */
#if defined(__clang__)
SDF__HOT_INLINE void closest_point_walk(const sdf__tree *tree, const float *positions,
                                        const uint32_t *triangles, float extent, const float p[3],
                                        double bound2, sdf__hit *hit)
#else
SDF__SIMD_CLONES
void sdf__closest_point(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                        float extent, const float p[3], double bound2, sdf__hit *hit)
#endif
{
    const float tie_abs = TIE_ABS_OF_EXTENT * extent;
    const float x = p[0], y = p[1], z = p[2];
    const sdf__v8f vx = sdf__v8f_splat(x), vy = sdf__v8f_splat(y), vz = sdf__v8f_splat(z);
    float limit2 = start_limit2(bound2, tie_abs);
    lane_state lane = {.best = INFINITY, .count = 0};
    /* Each wide level pushes at most SDF__WIDE children and pops one. */
    wide_entry stack[(SDF__WIDE - 1) * SDF__TREE_MAX_DEPTH + 2];
    int top = 0;
    stack[top++] = (wide_entry){0, 0.0f};
    while (top > 0) {
        const wide_entry e = stack[--top];
        if (e.dist2 > limit2) /* the bound shrank since it was pushed */
            continue;
        if (e.ref & SDF__WIDE_LEAF) {
            const uint32_t leaf = e.ref & ~SDF__WIDE_LEAF;
            if (sdf__disc_dist2f(&tree->discs[leaf], x, y, z) <= limit2)
                point_leaf(tree, &tree->nodes[leaf], positions, triangles, vx, vy, vz, &limit2,
                           tie_abs, &lane);
            continue;
        }
        const sdf__wide_node *w = &tree->wide.nodes[e.ref];
        const sdf__v8f d2 = wide_dist2(w, vx, vy, vz);
        /* The children within the bound, farthest first, so the nearest is popped first:
         * sorted as keys, the distance's bits (d2 >= 0 orders as an integer) with the
         * child's slot in the low three, the others INT32_MAX. Branchless: which children
         * pass, and their order, are coin flips to a branch predictor (the insertion sort
         * this replaced was a third of the walk). Clearing three bits rounds a distance
         * down, which only keeps a child a little longer. */
        sdf__v8i child;
        memcpy(&child, w->child, sizeof child);
        const sdf__v8i slot = {0, 1, 2, 3, 4, 5, 6, 7};
        sdf__v8i pass = (child != (int32_t)SDF__WIDE_EMPTY) & (d2 <= limit2);
        sdf__v8i keys = (((sdf__v8i)d2 & ~7) | slot) & pass;
        keys |= ~pass & INT32_MAX;
        keys = sdf__v8i_sort(keys);
        const sdf__v8i bit = {1, 2, 4, 8, 16, 32, 64, 128};
        int n = __builtin_popcount(sdf__v8i_or_lanes(pass & bit));
        for (int i = n - 1; i >= 0; i--) {
            uint32_t key = (uint32_t)keys[i];
            float dist2;
            uint32_t bits = key & ~7u;
            memcpy(&dist2, &bits, sizeof dist2);
            stack[top++] = (wide_entry){w->child[key & 7], dist2};
        }
    }
    double q[3] = {x, y, z};
    decide_lane(positions, triangles, q, &lane, tie_abs, hit);
}

#if defined(__clang__)
SDF__SIMD_CLONES
void sdf__closest_point(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                        float extent, const float p[3], double bound2, sdf__hit *hit)
{
    closest_point_walk(tree, positions, triangles, extent, p, bound2, hit);
}
#endif

/* Culling compares the double box distance against the best exact distance grown by this
 * factor: both round by ~1e-16, and a node as near as the best may hold a lower-numbered
 * tie, which the offer rule prefers. */
#define EXACT_CULL_SLACK (1 + 1e-9)

void sdf__closest_exact(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                        const float p[3], sdf__hit *hit)
{
    const double q[3] = {p[0], p[1], p[2]};
    hit->dist2 = INFINITY;
    hit->triangle = 0;
    uint32_t stack[SDF__TREE_MAX_DEPTH + 2];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const sdf__tree_node *node = &tree->nodes[stack[--top]];
        double box2 = 0;
        for (int a = 0; a < 3; a++) {
            double gap = q[a] < node->lo[a] ? node->lo[a] - q[a]
                         : q[a] > node->hi[a] ? q[a] - node->hi[a] : 0;
            box2 += gap * gap;
        }
        if (box2 > hit->dist2 * EXACT_CULL_SLACK)
            continue;
        if (node->count) {
            for (uint32_t k = 0; k < node->count; k++)
                sdf__triangle_offer(positions, triangles, tree->prims[node->first + k], q, hit);
            continue;
        }
        stack[top++] = node->first + 1; /* children in order: no need to be clever here */
        stack[top++] = node->first;
    }
}
