/* tree.h - a binary BVH over a mesh's triangles in a flat array of our own layout, built by
 * Embree's generic builder (rtcBuildBVH, SAH). Embree's own scene BVH is opaque, but
 * hierarchical algorithms need to attach data to nodes (the fast winding number keeps
 * multipole moments per node), so we build this tree and own its layout.
 *
 * Layout: nodes[0] is the root. A node with count > 0 is a leaf holding the triangles
 * prims[first .. first + count); otherwise its children are nodes[first] and nodes[first+1].
 * A parent always precedes its children, so a reverse sweep visits children first, and a
 * subtree's triangles are contiguous in prims. */
#ifndef SDF_BVH_TREE_H
#define SDF_BVH_TREE_H

#include <stddef.h>
#include <stdint.h>

#include "bvh/wide.h"

typedef struct sdf__bvh sdf__bvh;

typedef struct sdf__tree_node {
    float lo[3];
    uint32_t first;
    float hi[3];
    uint32_t count;
} sdf__tree_node;

/* A leaf's triangles lie in a flat cylinder: within `radius` of the axis through `centre`
 * along `normal` (unit), and within `half_height` of the plane through `centre` across it,
 * both widened past float rounding. The distance to the cylinder bounds the distance to
 * every triangle of the leaf from below, and where a box is a poor fit it is a far better
 * bound: the box of a surface patch tilted to the axes reaches out of the surface by about
 * the patch's size, so a point at distance d above it finds the boxes of every leaf within
 * ~sqrt(2 d s) (s: the leaves' size) as near as its closest triangle; the cylinders of all
 * but the leaves under it are farther. A leaf whose triangles have no area keeps an infinite
 * cylinder (it culls nothing). */
typedef struct sdf__tree_disc {
    float centre[3], radius;
    float normal[3], half_height;
} sdf__tree_disc;

typedef struct sdf__tree {
    sdf__tree_node *nodes;
    sdf__tree_disc *discs;  /* per node; meaningful at leaves */
    size_t node_count;
    uint32_t *prims;
    size_t prim_count;
    int depth; /* the longest root-to-leaf path, in nodes */
    float leaf_size; /* mean diagonal of the leaves' boxes: the scale packets share work at */
    sdf__wide wide;  /* the same tree eight-wide, for walks of one point (bvh/wide.h) */
} sdf__tree;

#define SDF__TREE_MAX_DEPTH 64
#define SDF__TREE_MAX_LEAF 32 /* triangles per leaf, at most */

/* Build over all triangles with at most `max_leaf` (1..32) per leaf, by the builder of
 * `bvh`'s Embree device (bvh/embree.h). Returns 0, SDF_ENOMEM, or SDF_EBVH (Embree failed, or the
 * tree is deeper than SDF__TREE_MAX_DEPTH). */
int sdf__tree_build(const sdf__bvh *bvh, const float *positions, const uint32_t *triangles,
                    size_t triangle_count, unsigned max_leaf, sdf__tree *out);
void sdf__tree_free(sdf__tree *tree);

#endif
