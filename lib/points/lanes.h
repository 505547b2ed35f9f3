/* lanes.h - float point-to-triangle and point-to-box distances for many points at once.
 *
 * The packet traversal and the cluster evaluation (packet.c, cluster.c) test one triangle
 * against eight points at a time, and the single-point walk (packet.c) eight triangles
 * against one point, branchless, on eight-lane vectors (AVX2 in the functions compiled
 * twice, core/simd.h; they must be inlined into such a function to be). Float distances
 * choose triangles; wherever a distance must be exact, the double test (triangle.h)
 * computes it. */
#ifndef SDF_POINTS_LANES_H
#define SDF_POINTS_LANES_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "bvh/tree.h" /* sdf__tree_disc */
#include "core/simd.h"

#define SDF__LANE_GROUP 8 /* points tested together: one AVX vector of floats */

/* The float triangle test below is accurate to about 10 ulps of (distance + triangle size).
 * A float comparison that must not lose a triangle is widened by SDF__LANE_SLACK_REL of the
 * distance plus SDF__LANE_SLACK_ABS_OF_EXTENT of the mesh's extent (its bounding-box
 * diagonal, which bounds every triangle's size): ~16x and ~6x that error. */
#define SDF__LANE_SLACK_REL 1e-5f
#define SDF__LANE_SLACK_ABS_OF_EXTENT 4e-6f

/* max/min of finite floats as plain comparisons, which compile to maxss/minss (and vector
 * max/min in loops): fminf's NaN rules stop the compiler from inlining it (it became a libm
 * call per box test). Our inputs are never NaN. */
static inline float sdf__minf(float a, float b) { return a < b ? a : b; }
static inline float sdf__maxf(float a, float b) { return a > b ? a : b; }

/* Squared distance from (x, y, z) to the box [lo, hi]; 0 inside. */
SDF__HOT_INLINE float sdf__box_dist2f(const float lo[3], const float hi[3], float x, float y,
                                      float z)
{
    float dx = sdf__maxf(sdf__maxf(lo[0] - x, x - hi[0]), 0.0f);
    float dy = sdf__maxf(sdf__maxf(lo[1] - y, y - hi[1]), 0.0f);
    float dz = sdf__maxf(sdf__maxf(lo[2] - z, z - hi[2]), 0.0f);
    return dx * dx + dy * dy + dz * dz;
}

/* Squared distance from (x, y, z) to a leaf's cylinder (bvh/tree.h); 0 inside. */
SDF__HOT_INLINE float sdf__disc_dist2f(const sdf__tree_disc *c, float x, float y, float z)
{
    float vx = x - c->centre[0], vy = y - c->centre[1], vz = z - c->centre[2];
    float h = vx * c->normal[0] + vy * c->normal[1] + vz * c->normal[2];
    /* The offset across the axis as a vector: |v|^2 - h^2 would cancel for points far
     * along the normal. */
    float wx = vx - h * c->normal[0], wy = vy - h * c->normal[1], wz = vz - h * c->normal[2];
    float a = sdf__maxf(sqrtf(wx * wx + wy * wy + wz * wz) - c->radius, 0.0f);
    float b = sdf__maxf(sdf__maxf(h, -h) - c->half_height, 0.0f);
    return a * a + b * b;
}

/* Eight lanes as one GCC/clang vector ("vector extensions": plain C operators, no
 * intrinsics); the compiler uses AVX for it in the x86-64-v3 clones and two SSE halves
 * elsewhere. Written as vectors rather than as lane loops because GCC hoisted the ~35
 * broadcast triangle fields out of the loop and spilled them: the same test ran in ~100
 * cycles per eight lanes, ~60 as vectors (a microbenchmark, one run). The helpers are always
 * inlined, so no vector crosses a function boundary (lib/meson.build: -Wno-psabi). */
typedef float sdf__v8f __attribute__((vector_size(32)));
typedef int32_t sdf__v8i __attribute__((vector_size(32)));

SDF__HOT_INLINE sdf__v8f sdf__v8f_load(const float *p)
{
    sdf__v8f v;
    memcpy(&v, p, sizeof v);
    return v;
}

SDF__HOT_INLINE sdf__v8f sdf__v8f_splat(float a) { return (sdf__v8f){0} + a; }

/* Lane-wise m ? a : b for a comparison mask m (all bits set or clear per lane). */
SDF__HOT_INLINE sdf__v8f sdf__v8f_select(sdf__v8i m, sdf__v8f a, sdf__v8f b)
{
    return (sdf__v8f)(((sdf__v8i)a & m) | ((sdf__v8i)b & ~m));
}

SDF__HOT_INLINE sdf__v8f sdf__v8f_min(sdf__v8f a, sdf__v8f b)
{
    return sdf__v8f_select(a < b, a, b);
}

SDF__HOT_INLINE sdf__v8f sdf__v8f_max(sdf__v8f a, sdf__v8f b)
{
    return sdf__v8f_select(a > b, a, b);
}

/* The OR of a mask's lanes, two lanes to each 64-bit half. */
SDF__HOT_INLINE uint64_t sdf__v8i_or_pairs(sdf__v8i m)
{
    uint64_t w[4];
    memcpy(w, &m, sizeof w);
    return w[0] | w[1] | w[2] | w[3];
}

/* Is any lane of the mask set? */
SDF__HOT_INLINE int sdf__v8i_any(sdf__v8i m)
{
    return sdf__v8i_or_pairs(m) != 0;
}

/* The OR of a vector's lanes (packets tag each group's lanes with the group's bit and reduce
 * once for all groups: a reduction per group took a tenth of the traversal). */
SDF__HOT_INLINE unsigned sdf__v8i_or_lanes(sdf__v8i v)
{
    uint64_t x = sdf__v8i_or_pairs(v);
    return (unsigned)(x | x >> 32);
}

/* Lane i of v8i `v` from its lane p[i], for a constant permutation p given as eight indices.
 * GCC spells a permutation __builtin_shuffle (a vector of indices), clang
 * __builtin_shufflevector (the indices as constant arguments); both compile a constant one to
 * the same single shuffle. */
#if defined(__clang__)
#define SDF__V8I_PERMUTE(v, p0, p1, p2, p3, p4, p5, p6, p7) \
    __builtin_shufflevector((v), (v), p0, p1, p2, p3, p4, p5, p6, p7)
#else
#define SDF__V8I_PERMUTE(v, p0, p1, p2, p3, p4, p5, p6, p7) \
    __builtin_shuffle((v), (sdf__v8i){p0, p1, p2, p3, p4, p5, p6, p7})
#endif

/* One layer of a sorting network on eight keys: lane i and lane partner[i] trade places when
 * out of order, where w holds each lane's partner's key; `first` marks the lower lane of each
 * pair (unpaired lanes are their own partner and keep their key). Branchless, so
 * unpredictable orders cost no mispredictions. */
SDF__HOT_INLINE sdf__v8i sdf__v8i_sort_layer(sdf__v8i v, sdf__v8i w, sdf__v8i first)
{
    sdf__v8i less = v < w;
    sdf__v8i lo = (v & less) | (w & ~less), hi = (w & less) | (v & ~less);
    return (lo & first) | (hi & ~first);
}

/* The eight keys in ascending order (Batcher's odd-even merge sort: 19 exchanges in six
 * layers; checked exhaustively on 0/1 inputs, which suffices for a sorting network). */
SDF__HOT_INLINE sdf__v8i sdf__v8i_sort(sdf__v8i v)
{
    v = sdf__v8i_sort_layer(v, SDF__V8I_PERMUTE(v, 1, 0, 3, 2, 5, 4, 7, 6),
                            (sdf__v8i){-1, 0, -1, 0, -1, 0, -1, 0});
    v = sdf__v8i_sort_layer(v, SDF__V8I_PERMUTE(v, 2, 3, 0, 1, 6, 7, 4, 5),
                            (sdf__v8i){-1, -1, 0, 0, -1, -1, 0, 0});
    v = sdf__v8i_sort_layer(v, SDF__V8I_PERMUTE(v, 0, 2, 1, 3, 4, 6, 5, 7),
                            (sdf__v8i){0, -1, 0, 0, 0, -1, 0, 0});
    v = sdf__v8i_sort_layer(v, SDF__V8I_PERMUTE(v, 4, 5, 6, 7, 0, 1, 2, 3),
                            (sdf__v8i){-1, -1, -1, -1, 0, 0, 0, 0});
    v = sdf__v8i_sort_layer(v, SDF__V8I_PERMUTE(v, 0, 1, 4, 5, 2, 3, 6, 7),
                            (sdf__v8i){0, 0, -1, -1, 0, 0, 0, 0});
    v = sdf__v8i_sort_layer(v, SDF__V8I_PERMUTE(v, 0, 2, 1, 4, 3, 6, 5, 7),
                            (sdf__v8i){0, -1, 0, -1, 0, -1, 0, 0});
    return v;
}

/* Lane-wise square root (vsqrtps where the vectorizer sees it: -fno-math-errno). */
SDF__HOT_INLINE sdf__v8f sdf__v8f_sqrt(sdf__v8f a)
{
    sdf__v8f r;
    for (int i = 0; i < 8; i++)
        r[i] = sqrtf(a[i]);
    return r;
}

/* Squared distance from eight points to a leaf's cylinder (bvh/tree.h); 0 inside. */
SDF__HOT_INLINE sdf__v8f sdf__disc_dist2_lanes(const sdf__tree_disc *c, sdf__v8f x, sdf__v8f y,
                                               sdf__v8f z)
{
    const sdf__v8f zero = sdf__v8f_splat(0);
    sdf__v8f vx = x - c->centre[0], vy = y - c->centre[1], vz = z - c->centre[2];
    sdf__v8f h = vx * c->normal[0] + vy * c->normal[1] + vz * c->normal[2];
    sdf__v8f wx = vx - h * c->normal[0], wy = vy - h * c->normal[1], wz = vz - h * c->normal[2];
    sdf__v8f a = sdf__v8f_max(sdf__v8f_sqrt(wx * wx + wy * wy + wz * wz) - c->radius, zero);
    sdf__v8f b = sdf__v8f_max(sdf__v8f_max(h, -h) - c->half_height, zero);
    return a * a + b * b;
}

/* Squared distance from each lane's point (x, y, z) to that lane's box [lo, hi]; 0 inside.
 * Eight points and one box (sdf__box_dist2_lanes), or one point and a wide node's eight
 * boxes (bvh/wide.h), are the two uses. */
SDF__HOT_INLINE sdf__v8f sdf__box_dist2_v8(const sdf__v8f lo[3], const sdf__v8f hi[3],
                                           sdf__v8f x, sdf__v8f y, sdf__v8f z)
{
    const sdf__v8f zero = sdf__v8f_splat(0);
    sdf__v8f dx = sdf__v8f_max(sdf__v8f_max(lo[0] - x, x - hi[0]), zero);
    sdf__v8f dy = sdf__v8f_max(sdf__v8f_max(lo[1] - y, y - hi[1]), zero);
    sdf__v8f dz = sdf__v8f_max(sdf__v8f_max(lo[2] - z, z - hi[2]), zero);
    return dx * dx + dy * dy + dz * dz;
}

/* Squared distance from eight points to the box [lo, hi]; 0 inside. */
SDF__HOT_INLINE sdf__v8f sdf__box_dist2_lanes(const float lo[3], const float hi[3], sdf__v8f x,
                                              sdf__v8f y, sdf__v8f z)
{
    const sdf__v8f l[3] = {sdf__v8f_splat(lo[0]), sdf__v8f_splat(lo[1]), sdf__v8f_splat(lo[2])};
    const sdf__v8f h[3] = {sdf__v8f_splat(hi[0]), sdf__v8f_splat(hi[1]), sdf__v8f_splat(hi[2])};
    return sdf__box_dist2_v8(l, h, x, y, z);
}

/* Eight triangles prepared for the float test, lane t holding triangle t (or one triangle in
 * every lane, to test it against eight points): corners, edges k = v[k] -> v[k+1], their
 * inverse squared lengths (0 for a zero-length edge), the face normal n with 1/|n|^2, the
 * in-plane inward edge normals m[k] = n x e[k], and face = 0, or -INFINITY for a zero-area
 * (in float) triangle, of which only the edges count. */
typedef struct sdf__triangle8 {
    sdf__v8f v[3][3], e[3][3], inv_len2[3], n[3], inv_n2, m[3][3], face;
} sdf__triangle8;

/* Fill the rest of `f` from its corners f->v. */
SDF__HOT_INLINE void sdf__triangle8_prepare(sdf__triangle8 *f)
{
    const sdf__v8f zero = sdf__v8f_splat(0);
    for (int k = 0; k < 3; k++) {
        sdf__v8f len2 = zero;
        for (int i = 0; i < 3; i++) {
            f->e[k][i] = f->v[(k + 1) % 3][i] - f->v[k][i];
            len2 += f->e[k][i] * f->e[k][i];
        }
        f->inv_len2[k] = sdf__v8f_select(len2 > 0, 1.0f / len2, zero);
    }
    const sdf__v8f *e0 = f->e[0], *e2 = f->e[2]; /* n = e0 x (v2 - v0) = e0 x -e2 */
    f->n[0] = e2[1] * e0[2] - e2[2] * e0[1];
    f->n[1] = e2[2] * e0[0] - e2[0] * e0[2];
    f->n[2] = e2[0] * e0[1] - e2[1] * e0[0];
    sdf__v8f n2 = f->n[0] * f->n[0] + f->n[1] * f->n[1] + f->n[2] * f->n[2];
    sdf__v8i has_face = (n2 > 0) & (1.0f / n2 < INFINITY);
    f->face = sdf__v8f_select(has_face, zero, sdf__v8f_splat(-INFINITY));
    f->inv_n2 = sdf__v8f_select(has_face, 1.0f / n2, zero);
    for (int k = 0; k < 3; k++) {
        const sdf__v8f *e = f->e[k];
        f->m[k][0] = f->n[1] * e[2] - f->n[2] * e[1];
        f->m[k][1] = f->n[2] * e[0] - f->n[0] * e[2];
        f->m[k][2] = f->n[0] * e[1] - f->n[1] * e[0];
    }
}

/* Squared distance from q (relative to edge k's start) to edge k's segment. */
SDF__HOT_INLINE sdf__v8f sdf__edge8_dist2(const sdf__triangle8 *f, int k, sdf__v8f qx, sdf__v8f qy,
                                          sdf__v8f qz)
{
    const sdf__v8f *e = f->e[k];
    sdf__v8f t = (qx * e[0] + qy * e[1] + qz * e[2]) * f->inv_len2[k];
    t = sdf__v8f_min(sdf__v8f_max(t, sdf__v8f_splat(0)), sdf__v8f_splat(1));
    sdf__v8f rx = qx - t * e[0], ry = qy - t * e[1], rz = qz - t * e[2];
    return rx * rx + ry * ry + rz * rz;
}

/* Squared distance from point (x, y, z) of each lane to the triangle of that lane, in float,
 * without branches: inside the prism over the face it is the distance to the plane, outside
 * it the nearest of the three edge segments (the closest point of a triangle lies on its
 * boundary when the projection falls outside). Accurate to about 10 ulps of (distance +
 * triangle size). */
SDF__HOT_INLINE sdf__v8f sdf__triangle8_dist2(const sdf__triangle8 *f, sdf__v8f x, sdf__v8f y,
                                              sdf__v8f z)
{
    const sdf__v8f *v0 = f->v[0], *v1 = f->v[1], *v2 = f->v[2];
    sdf__v8f ax = x - v0[0], ay = y - v0[1], az = z - v0[2];
    sdf__v8f bx = x - v1[0], by = y - v1[1], bz = z - v1[2];
    sdf__v8f cx = x - v2[0], cy = y - v2[1], cz = z - v2[2];
    sdf__v8f side0 = ax * f->m[0][0] + ay * f->m[0][1] + az * f->m[0][2];
    sdf__v8f side1 = bx * f->m[1][0] + by * f->m[1][1] + bz * f->m[1][2];
    sdf__v8f side2 = cx * f->m[2][0] + cy * f->m[2][1] + cz * f->m[2][2];
    sdf__v8f side = sdf__v8f_min(sdf__v8f_min(side0, side1), side2) + f->face;
    sdf__v8f plane = ax * f->n[0] + ay * f->n[1] + az * f->n[2];
    sdf__v8f plane_d2 = plane * plane * f->inv_n2;
    sdf__v8f edges = sdf__v8f_min(sdf__v8f_min(sdf__edge8_dist2(f, 0, ax, ay, az),
                                               sdf__edge8_dist2(f, 1, bx, by, bz)),
                                  sdf__edge8_dist2(f, 2, cx, cy, cz));
    return sdf__v8f_select(side >= 0, plane_d2, edges);
}

/* One prepared triangle stored compactly (the cluster's candidates): the fields of
 * sdf__triangle8 for a single triangle. */
typedef struct sdf__float_triangle {
    float v[3][3], e[3][3], inv_len2[3], n[3], inv_n2, m[3][3], face;
} sdf__float_triangle;

/* Fill the rest of `f` from its corners f->v (by sdf__triangle8_prepare on its lane 0). */
SDF__HOT_INLINE void sdf__float_triangle_prepare(sdf__float_triangle *f)
{
    sdf__triangle8 t;
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++)
            t.v[k][a] = sdf__v8f_splat(f->v[k][a]);
    sdf__triangle8_prepare(&t);
    for (int k = 0; k < 3; k++) {
        for (int a = 0; a < 3; a++)
            f->e[k][a] = t.e[k][a][0], f->m[k][a] = t.m[k][a][0];
        f->inv_len2[k] = t.inv_len2[k][0], f->n[k] = t.n[k][0];
    }
    f->inv_n2 = t.inv_n2[0], f->face = t.face[0];
}

/* The triangle's squared float distance from eight points. */
SDF__HOT_INLINE sdf__v8f sdf__triangle_lanes(const sdf__float_triangle *f, sdf__v8f x, sdf__v8f y,
                                             sdf__v8f z)
{
    sdf__triangle8 t;
    for (int k = 0; k < 3; k++) {
        for (int a = 0; a < 3; a++) {
            t.v[k][a] = sdf__v8f_splat(f->v[k][a]), t.e[k][a] = sdf__v8f_splat(f->e[k][a]);
            t.m[k][a] = sdf__v8f_splat(f->m[k][a]);
        }
        t.inv_len2[k] = sdf__v8f_splat(f->inv_len2[k]), t.n[k] = sdf__v8f_splat(f->n[k]);
    }
    t.inv_n2 = sdf__v8f_splat(f->inv_n2), t.face = sdf__v8f_splat(f->face);
    return sdf__triangle8_dist2(&t, x, y, z);
}

#endif
