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

#include <embree3/rtcore.h>

typedef struct sdf__tree_node {
    float lo[3];
    uint32_t first;
    float hi[3];
    uint32_t count;
} sdf__tree_node;

typedef struct sdf__tree {
    sdf__tree_node *nodes;
    size_t node_count;
    uint32_t *prims;
    size_t prim_count;
    int depth; /* the longest root-to-leaf path, in nodes */
    float leaf_size; /* mean diagonal of the leaves' boxes: the scale packets share work at */
} sdf__tree;

#define SDF__TREE_MAX_DEPTH 64
#define SDF__TREE_MAX_LEAF 32 /* triangles per leaf, at most */

/* Build over all triangles with at most `max_leaf` (1..32) per leaf. Returns 0, SDF_ENOMEM,
 * or SDF_EBVH (Embree failed, or the tree is deeper than SDF__TREE_MAX_DEPTH). */
int sdf__tree_build(RTCDevice device, const float *positions, const uint32_t *triangles,
                    size_t triangle_count, unsigned max_leaf, sdf__tree *out);
void sdf__tree_free(sdf__tree *tree);

#endif
