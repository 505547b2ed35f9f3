/* packet.c - Morton order and packet traversal (see packet.h). */
#include "query/packet.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/simd.h"
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
 * grown by this factor so rounding can never cull the node that holds the true closest
 * point. */
#define CULL_SLACK 1.00001f

/* The float triangle test below is accurate to about 10 ulps of (d + triangle size): every
 * triangle whose float distance is within TIE_REL * d + TIE_ABS of a lane's best float
 * distance is a candidate, and the candidates get the exact double test. TIE_ABS is a
 * fraction of the mesh's extent (the bounding-box diagonal sdf__closest_packet is given,
 * which bounds every triangle's size). The margins are ~16x and ~6x
 * the error bound, and cost nothing measurable: near ties are rare except at shared vertices
 * and edges, which the exact test must see anyway. */
#define TIE_REL 1e-5f
#define TIE_ABS_OF_EXTENT 4e-6f

/* max/min of finite floats as plain comparisons, which compile to maxss/minss (and vector
 * max/min in loops): fmaxf's NaN rules stop the compiler from inlining it (it became a libm
 * call per box test). Our inputs are never NaN. */
static inline float minf(float a, float b) { return a < b ? a : b; }
static inline float maxf(float a, float b) { return a > b ? a : b; }
static inline float max0(float a, float b) { return maxf(maxf(a, b), 0.0f); }
static inline float clamp01(float t) { return minf(maxf(t, 0.0f), 1.0f); }

/* Squared distance from (x, y, z) to the box [lo, hi]; 0 inside. */
SDF__HOT_INLINE float box_dist2(const float lo[3], const float hi[3], float x, float y,
                                float z)
{
    float dx = max0(lo[0] - x, x - hi[0]);
    float dy = max0(lo[1] - y, y - hi[1]);
    float dz = max0(lo[2] - z, z - hi[2]);
    return dx * dx + dy * dy + dz * dz;
}

/* Lanes are handled in groups of LANE_GROUP (one AVX vector of floats): a triangle gets the
 * full float test only in the groups that have a lane near its box. */
#define LANE_GROUP 8
#define LANE_GROUPS (SDF__PACKET / LANE_GROUP)
_Static_assert(SDF__PACKET % LANE_GROUP == 0 && LANE_GROUP == sizeof(uint64_t),
               "groups_near_box reads a group's 8 one-byte flags as one word");

/* Bit g set: some lane of group g lies within its limit of the box [lo, hi]. The distances
 * of all lanes (padded) come from one straight-line SoA loop the compiler vectorizes. */
SDF__HOT_INLINE unsigned groups_near_box(const sdf__packet *pk, const float *limit2,
                                         const float lo[3], const float hi[3])
{
    uint8_t near[SDF__PACKET];
    for (int i = 0; i < SDF__PACKET; i++)
        near[i] = box_dist2(lo, hi, pk->x[i], pk->y[i], pk->z[i]) <= limit2[i];
    unsigned mask = 0;
    for (int g = 0; g < LANE_GROUPS; g++) {
        uint64_t any;
        memcpy(&any, near + g * LANE_GROUP, sizeof any);
        mask |= (any != 0) << g;
    }
    return mask;
}

/* One triangle prepared for the float lane test: corners, edges k = v[k] -> v[k+1], their
 * inverse squared lengths (0 for a zero-length edge), the face normal n with 1/|n|^2, and
 * the in-plane inward edge normals m[k] = n x e[k]. */
typedef struct float_triangle {
    float v[3][3], e[3][3], inv_len2[3], n[3], inv_n2, m[3][3];
    int has_face; /* 0: zero area (float), only its edges count */
} float_triangle;

/* Fill the rest of `f` from its corners f->v. */
SDF__HOT_INLINE void prepare_triangle(float_triangle *f)
{
    for (int k = 0; k < 3; k++) {
        const float *a = f->v[k], *b = f->v[(k + 1) % 3];
        float len2 = 0;
        for (int i = 0; i < 3; i++) {
            f->e[k][i] = b[i] - a[i];
            len2 += f->e[k][i] * f->e[k][i];
        }
        f->inv_len2[k] = len2 > 0 ? 1.0f / len2 : 0.0f;
    }
    const float *e0 = f->e[0], *e2 = f->e[2]; /* n = e0 x (v2 - v0) = e0 x -e2 */
    f->n[0] = e2[1] * e0[2] - e2[2] * e0[1];
    f->n[1] = e2[2] * e0[0] - e2[0] * e0[2];
    f->n[2] = e2[0] * e0[1] - e2[1] * e0[0];
    float n2 = f->n[0] * f->n[0] + f->n[1] * f->n[1] + f->n[2] * f->n[2];
    f->has_face = n2 > 0 && isfinite(1.0f / n2);
    f->inv_n2 = f->has_face ? 1.0f / n2 : 0.0f;
    for (int k = 0; k < 3; k++) {
        const float *e = f->e[k];
        f->m[k][0] = f->n[1] * e[2] - f->n[2] * e[1];
        f->m[k][1] = f->n[2] * e[0] - f->n[0] * e[2];
        f->m[k][2] = f->n[0] * e[1] - f->n[1] * e[0];
    }
}

/* Squared distance from every lane to the triangle, in float, without branches: inside the
 * prism over the face it is the distance to the plane, outside it the nearest of the three
 * edge segments (the closest point of a triangle lies on its boundary when the projection
 * falls outside). */
SDF__HOT_INLINE float edge_dist2(const float_triangle *f, int k, float qx, float qy, float qz)
{
    const float *e = f->e[k];
    float t = clamp01((qx * e[0] + qy * e[1] + qz * e[2]) * f->inv_len2[k]);
    float rx = qx - t * e[0], ry = qy - t * e[1], rz = qz - t * e[2];
    return rx * rx + ry * ry + rz * rz;
}

SDF__HOT_INLINE float side_of(const float_triangle *f, int k, float qx, float qy, float qz)
{
    return qx * f->m[k][0] + qy * f->m[k][1] + qz * f->m[k][2];
}

SDF__HOT_INLINE void triangle_lanes(const float_triangle *f, const sdf__packet *pk, int group,
                                    float *dist2)
{
    const float *px = pk->x + group * LANE_GROUP, *py = pk->y + group * LANE_GROUP,
                *pz = pk->z + group * LANE_GROUP;
    const float *v0 = f->v[0], *v1 = f->v[1], *v2 = f->v[2];
    /* A zero-area triangle never takes the face branch: its side tests are made to fail. */
    const float face = f->has_face ? 0.0f : -INFINITY;
    for (int i = 0; i < LANE_GROUP; i++) {
        float ax = px[i] - v0[0], ay = py[i] - v0[1], az = pz[i] - v0[2];
        float bx = px[i] - v1[0], by = py[i] - v1[1], bz = pz[i] - v1[2];
        float cx = px[i] - v2[0], cy = py[i] - v2[1], cz = pz[i] - v2[2];
        float side = minf(minf(side_of(f, 0, ax, ay, az), side_of(f, 1, bx, by, bz)),
                          side_of(f, 2, cx, cy, cz)) + face;
        float plane = ax * f->n[0] + ay * f->n[1] + az * f->n[2];
        float plane_d2 = plane * plane * f->inv_n2;
        float edges = minf(minf(edge_dist2(f, 0, ax, ay, az), edge_dist2(f, 1, bx, by, bz)),
                           edge_dist2(f, 2, cx, cy, cz));
        dist2[i] = side >= 0.0f ? plane_d2 : edges;
    }
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
        *limit2 = minf(*limit2, lim * lim);
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
        float_triangle f; /* corners loaded once: for the box test, then for the lane test */
        for (int c = 0; c < 3; c++)
            memcpy(f.v[c], positions + 3 * (size_t)t[c], 3 * sizeof(float));
        float lo[3], hi[3];
        for (int a = 0; a < 3; a++) {
            lo[a] = minf(minf(f.v[0][a], f.v[1][a]), f.v[2][a]);
            hi[a] = maxf(maxf(f.v[0][a], f.v[1][a]), f.v[2][a]);
        }
        unsigned near = groups & groups_near_box(pk, limit2, lo, hi);
        if (!near)
            continue;
        prepare_triangle(&f);
        for (int g = 0; g < LANE_GROUPS; g++) {
            if (!(near >> g & 1))
                continue;
            float d2[LANE_GROUP];
            triangle_lanes(&f, pk, g, d2);
            uint8_t within[LANE_GROUP]; /* vector compare; lanes that pass are rare */
            for (int j = 0; j < LANE_GROUP; j++)
                within[j] = d2[j] <= limit2[g * LANE_GROUP + j];
            uint64_t any;
            memcpy(&any, within, sizeof any);
            for (int j = 0; any && j < LANE_GROUP; j++)
                if (within[j])
                    lane_offer(&lanes[g * LANE_GROUP + j], &limit2[g * LANE_GROUP + j], tie_abs,
                               tri, d2[j]);
        }
    }
}

/* The exact double test over a lane's candidates decides its closest point. */
static void exact_lane(const float *positions, const uint32_t *triangles, const sdf__packet *pk,
                       int i, const lane_state *s, float limit2, sdf__hit *hit)
{
    hit->dist2 = INFINITY;
    hit->triangle = 0;
    double p[3] = {pk->x[i], pk->y[i], pk->z[i]};
    for (int c = 0; c < s->count; c++) {
        if (s->dist2[c] > limit2)
            continue;
        const uint32_t *t = triangles + 3 * (size_t)s->tri[c];
        double v[3][3], closest[3], bary[3];
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++)
                v[k][a] = positions[3 * (size_t)t[k] + a];
        int feature;
        double d2 = sdf__closest_on_triangle(p, v[0], v[1], v[2], closest, bary, &feature);
        if (d2 < hit->dist2 || (d2 == hit->dist2 && s->tri[c] < hit->triangle)) {
            hit->dist2 = d2;
            sdf__triangle_normal(v[0], v[1], v[2], hit->face_normal);
            hit->triangle = s->tri[c];
            hit->feature = feature;
            memcpy(hit->point, closest, sizeof closest);
            memcpy(hit->bary, bary, sizeof bary);
        }
    }
}

SDF__SIMD_CLONES
void sdf__closest_packet(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                         float extent, sdf__packet *pk, sdf__hit *hits)
{
    float tie_abs = TIE_ABS_OF_EXTENT * extent;
    float limit2[SDF__PACKET], cx = 0, cy = 0, cz = 0;
    lane_state lanes[SDF__PACKET];
    for (int i = 0; i < SDF__PACKET; i++) {
        /* The true closest triangle's float distance is at most its true distance plus the
         * float error, so the seeded bound gets the tie margin too. Padding lanes never
         * match (limit -1). */
        float bound = (float)sqrt(pk->bound2[i]);
        float lim = bound * (1 + TIE_REL) + tie_abs;
        limit2[i] = i < pk->n ? lim * lim * CULL_SLACK : -1.0f;
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
            visit_leaf(tree, node, positions, triangles, pk, groups, limit2, tie_abs, lanes);
            continue;
        }
        /* Near child last on the stack, so it is visited first and shrinks the bounds. */
        const sdf__tree_node *a = &tree->nodes[node->first], *b = a + 1;
        float da = box_dist2(a->lo, a->hi, cx, cy, cz), db = box_dist2(b->lo, b->hi, cx, cy, cz);
        uint32_t near = da <= db ? node->first : node->first + 1;
        stack[top++] = near == node->first ? node->first + 1 : node->first;
        stack[top++] = near;
    }
    for (int i = 0; i < pk->n; i++) {
        if (lanes[i].count > MAX_CANDIDATES) { /* too many near ties to hold: ask again */
            hits[i].dist2 = INFINITY;
            continue;
        }
        float lim = lanes[i].best * (1 + TIE_REL) + tie_abs;
        exact_lane(positions, triangles, pk, i, &lanes[i], lim * lim, &hits[i]);
    }
}
