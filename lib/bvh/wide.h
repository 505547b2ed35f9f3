/* wide.h - an eight-wide view of the binary BVH (bvh/tree.h) for walks of one point.
 *
 * One point walking the binary tree tests two boxes per level, one at a time, and a level
 * is a dependent load, and a query near the surface visits dozens of them. Collapsing
 * the tree so that each node holds up to eight descendants, their boxes stored as arrays
 * over the eight (SoA), tests all eight with one vector operation per axis and takes a
 * third of the levels. The leaves stay the binary tree's (their triangles, their cylinders),
 * so every walk sees the same leaves and the same float tests as before.
 *
 * Collapse rule (the usual one): starting from a binary node's two children, the inner
 * child with the largest box surface is replaced by its own two children until there are
 * eight or all are leaves; each inner child left becomes a wide node of its own. */
#ifndef SDF_BVH_WIDE_H
#define SDF_BVH_WIDE_H

#include <stddef.h>
#include <stdint.h>

#define SDF__WIDE 8 /* children per wide node */

/* A child reference: a wide node's index, or with SDF__WIDE_LEAF set, the binary tree's
 * index of a leaf node. A node's children come first; unused slots after them hold
 * SDF__WIDE_EMPTY and empty boxes (lo = +inf, hi = -inf). */
#define SDF__WIDE_LEAF 0x80000000u
#define SDF__WIDE_EMPTY UINT32_MAX

typedef struct sdf__wide_node {
    float lo[3][SDF__WIDE], hi[3][SDF__WIDE]; /* lo[axis][child] */
    uint32_t child[SDF__WIDE];
} sdf__wide_node;

typedef struct sdf__wide {
    sdf__wide_node *nodes; /* nodes[0] is the root */
    size_t count;
} sdf__wide;

struct sdf__tree_node;

/* Build the wide view of a binary tree of `node_count` nodes (root nodes[0]; an inner node's
 * children are nodes[first] and nodes[first + 1]). Returns 0, SDF_ENOMEM, or SDF_EBVH (more
 * nodes than a reference can name). */
int sdf__wide_build(const struct sdf__tree_node *nodes, size_t node_count, sdf__wide *out);
void sdf__wide_free(sdf__wide *wide);

#endif
