/* tree.c - our flat binary BVH, built with rtcBuildBVH (see tree.h).
 *
 * Embree's builder calls back to create nodes and leaves in memory from its thread-local
 * allocator; we then flatten that temporary tree depth-first into our arrays and release
 * Embree's copy. */
#include "bvh/tree.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <embree3/rtcore.h>

#include "bvh/embree.h"
#include "core/parallel.h"
#include "sdf/sdf.h"

/* Temporary nodes living in Embree's allocator until flattened. */
typedef struct build_node {
    int is_leaf;
    unsigned count;           /* leaf: number of prims */
    struct build_node *child[2];
    struct RTCBounds bounds[2];
    unsigned prims[];         /* leaf: triangle ids */
} build_node;

static void *create_node(RTCThreadLocalAllocator alloc, unsigned int child_count, void *user)
{
    (void)child_count;
    (void)user;
    build_node *n = rtcThreadLocalAlloc(alloc, sizeof *n, 16);
    if (n)
        memset(n, 0, sizeof *n);
    return n;
}

static void set_children(void *node, void **children, unsigned int count, void *user)
{
    (void)user;
    build_node *n = node;
    for (unsigned i = 0; i < count && i < 2; i++)
        n->child[i] = children[i];
}

static void set_bounds(void *node, const struct RTCBounds **bounds, unsigned int count, void *user)
{
    (void)user;
    build_node *n = node;
    for (unsigned i = 0; i < count && i < 2; i++)
        n->bounds[i] = *bounds[i];
}

static void *create_leaf(RTCThreadLocalAllocator alloc, const struct RTCBuildPrimitive *prims,
                         size_t count, void *user)
{
    (void)user;
    build_node *n = rtcThreadLocalAlloc(alloc, sizeof *n + count * sizeof(unsigned), 16);
    if (!n)
        return NULL;
    memset(n, 0, sizeof *n);
    n->is_leaf = 1;
    n->count = (unsigned)count;
    for (size_t i = 0; i < count; i++)
        n->prims[i] = prims[i].primID;
    return n;
}

typedef struct flattener {
    sdf__tree *tree;
    size_t next_node, next_prim;
} flattener;

static void set_node_bounds(sdf__tree_node *dst, const struct RTCBounds *b)
{
    dst->lo[0] = b->lower_x, dst->lo[1] = b->lower_y, dst->lo[2] = b->lower_z;
    dst->hi[0] = b->upper_x, dst->hi[1] = b->upper_y, dst->hi[2] = b->upper_z;
}

/* Write `src` (whose bounds the caller set) into slot `index`; returns 0 or -1 if too deep. */
static int flatten(flattener *f, const build_node *src, size_t index, int depth)
{
    sdf__tree *t = f->tree;
    if (depth > t->depth)
        t->depth = depth;
    if (depth > SDF__TREE_MAX_DEPTH)
        return -1;
    sdf__tree_node *dst = &t->nodes[index];
    if (src->is_leaf) {
        dst->first = (uint32_t)f->next_prim;
        dst->count = src->count;
        memcpy(t->prims + f->next_prim, src->prims, src->count * sizeof(uint32_t));
        f->next_prim += src->count;
        return 0;
    }
    size_t left = f->next_node;
    f->next_node += 2;
    dst->first = (uint32_t)left;
    dst->count = 0;
    for (int i = 0; i < 2; i++) {
        set_node_bounds(&t->nodes[left + i], &src->bounds[i]);
        if (flatten(f, src->child[i], left + i, depth + 1))
            return -1;
    }
    return 0;
}

/* Cylinder bounds are widened by this much of the tree's size (its root box's diagonal),
 * and by the same fraction of themselves: a float evaluation of the distance to a cylinder
 * at points within ~10 diagonals of the mesh rounds by less (a few ulps of the point's
 * offset from the centre); farther out the searches' own relative tie margin (1e-5,
 * points/lanes.h) dwarfs the rounding. */
#define DISC_SLACK 4e-6

/* The cylinder of the leaf holding prims[first .. first + count) (tree.h): the axis along
 * their area-weighted normal, through the centre of their corners' box, and the radius and
 * half height that hold all their corners, measured in double from the float centre and
 * normal as stored. */
static void leaf_disc(const sdf__tree *t, uint32_t first, uint32_t count,
                      const float *positions, const uint32_t *triangles, double slack,
                      sdf__tree_disc *disc)
{
    double sum[3] = {0, 0, 0};
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t *tri = triangles + 3 * (size_t)t->prims[first + k];
        double v[3][3];
        for (int c = 0; c < 3; c++)
            for (int a = 0; a < 3; a++) {
                float x = positions[3 * (size_t)tri[c] + a];
                v[c][a] = x;
                lo[a] = x < lo[a] ? x : lo[a], hi[a] = x > hi[a] ? x : hi[a];
            }
        double e1[3], e2[3];
        for (int a = 0; a < 3; a++)
            e1[a] = v[1][a] - v[0][a], e2[a] = v[2][a] - v[0][a];
        sum[0] += e1[1] * e2[2] - e1[2] * e2[1];
        sum[1] += e1[2] * e2[0] - e1[0] * e2[2];
        sum[2] += e1[0] * e2[1] - e1[1] * e2[0];
    }
    double len = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
    for (int a = 0; a < 3; a++) {
        disc->centre[a] = 0.5f * (lo[a] + hi[a]);
        disc->normal[a] = len > 0 ? (float)(sum[a] / len) : (float)(a == 2);
    }
    if (!(len > 0)) {
        disc->radius = disc->half_height = INFINITY;
        return;
    }
    double radius2 = 0, height = 0;
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t *tri = triangles + 3 * (size_t)t->prims[first + k];
        for (int c = 0; c < 3; c++) {
            double d[3], h = 0, lateral2 = 0;
            for (int a = 0; a < 3; a++) {
                d[a] = (double)positions[3 * (size_t)tri[c] + a] - disc->centre[a];
                h += d[a] * disc->normal[a];
            }
            for (int a = 0; a < 3; a++) {
                double w = d[a] - h * disc->normal[a];
                lateral2 += w * w;
            }
            radius2 = fmax(radius2, lateral2);
            height = fmax(height, fabs(h));
        }
    }
    disc->radius = (float)(sqrt(radius2) * (1 + DISC_SLACK) + slack);
    disc->half_height = (float)(height * (1 + DISC_SLACK) + slack);
}

typedef struct discs_job {
    sdf__tree *tree;
    const float *positions;
    const uint32_t *triangles;
    double slack;
} discs_job;

/* Leaves only: at inner nodes (subtrees of up to 16..256 triangles) the cylinders cut the
 * nodes visited, but the extra test costs more than the visits it saves. */
static void discs_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const discs_job *job = ctx;
    sdf__tree *t = job->tree;
    for (size_t i = begin; i < end; i++) {
        const sdf__tree_node *n = &t->nodes[i];
        if (n->count)
            leaf_disc(t, n->first, n->count, job->positions, job->triangles, job->slack,
                      &t->discs[i]);
        else
            memset(&t->discs[i], 0, sizeof t->discs[i]);
    }
}

static float mean_leaf_diagonal(const sdf__tree *t)
{
    double sum = 0;
    size_t leaves = 0;
    for (size_t i = 0; i < t->node_count; i++) {
        const sdf__tree_node *n = &t->nodes[i];
        if (!n->count)
            continue;
        double d2 = 0;
        for (int a = 0; a < 3; a++)
            d2 += ((double)n->hi[a] - n->lo[a]) * ((double)n->hi[a] - n->lo[a]);
        sum += sqrt(d2);
        leaves++;
    }
    return leaves ? (float)(sum / (double)leaves) : 0.0f;
}

int sdf__tree_build(const sdf__bvh *embree, const float *positions, const uint32_t *triangles,
                    size_t triangle_count, unsigned max_leaf, sdf__tree *out)
{
    memset(out, 0, sizeof *out);
    struct RTCBuildPrimitive *prims = aligned_alloc(32, (triangle_count + 1) * sizeof *prims);
    if (!prims)
        return SDF_ENOMEM;
    struct RTCBounds root = {FLT_MAX, FLT_MAX, FLT_MAX, 0, -FLT_MAX, -FLT_MAX, -FLT_MAX, 0};
    for (size_t t = 0; t < triangle_count; t++) {
        float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
        for (int k = 0; k < 3; k++) {
            const float *v = positions + 3 * triangles[3 * t + k];
            for (int i = 0; i < 3; i++) {
                lo[i] = v[i] < lo[i] ? v[i] : lo[i];
                hi[i] = v[i] > hi[i] ? v[i] : hi[i];
            }
        }
        prims[t] = (struct RTCBuildPrimitive){lo[0], lo[1], lo[2], 0, hi[0], hi[1], hi[2],
                                              (unsigned)t};
        root.lower_x = lo[0] < root.lower_x ? lo[0] : root.lower_x;
        root.lower_y = lo[1] < root.lower_y ? lo[1] : root.lower_y;
        root.lower_z = lo[2] < root.lower_z ? lo[2] : root.lower_z;
        root.upper_x = hi[0] > root.upper_x ? hi[0] : root.upper_x;
        root.upper_y = hi[1] > root.upper_y ? hi[1] : root.upper_y;
        root.upper_z = hi[2] > root.upper_z ? hi[2] : root.upper_z;
    }
    RTCBVH bvh = rtcNewBVH(sdf__bvh_device(embree));
    struct RTCBuildArguments args = rtcDefaultBuildArguments();
    args.buildQuality = RTC_BUILD_QUALITY_MEDIUM;
    args.maxBranchingFactor = 2;
    args.maxDepth = SDF__TREE_MAX_DEPTH;
    /* A node visit costs about as much as 8 triangle tests in our traversals: the SAH then
     * makes leaves of ~6 triangles instead of ~2, which halves the node count (memory) and
     * shortens the walks, whose cost is the node visits' dependent loads. */
    args.traversalCost = 8.0f;
    args.maxLeafSize = max_leaf < 1 ? 1 : (max_leaf > SDF__TREE_MAX_LEAF ? SDF__TREE_MAX_LEAF : max_leaf);
    args.bvh = bvh;
    args.primitives = prims;
    args.primitiveCount = triangle_count;
    args.primitiveArrayCapacity = triangle_count;
    args.createNode = create_node;
    args.setNodeChildren = set_children;
    args.setNodeBounds = set_bounds;
    args.createLeaf = create_leaf;
    build_node *top = bvh ? rtcBuildBVH(&args) : NULL;
    free(prims);
    int rc = top ? 0 : SDF_EBVH;
    if (!rc) {
        /* A binary tree over n >= 1 leaves of >= 1 prim has at most 2n - 1 nodes. */
        out->nodes = calloc(2 * triangle_count, sizeof *out->nodes);
        out->prims = malloc(triangle_count * sizeof *out->prims);
        rc = out->nodes && out->prims ? 0 : SDF_ENOMEM;
    }
    if (!rc) {
        flattener f = {out, 1, 0};
        set_node_bounds(&out->nodes[0], &root);
        rc = flatten(&f, top, 0, 1) ? SDF_EBVH : 0;
        out->node_count = f.next_node;
        out->prim_count = f.next_prim;
        out->leaf_size = mean_leaf_diagonal(out);
        out->discs = malloc((out->node_count + 1) * sizeof *out->discs);
        rc = out->discs ? 0 : SDF_ENOMEM;
    }
    if (!rc)
        rc = sdf__wide_build(out->nodes, out->node_count, &out->wide);
    if (!rc) {
        const sdf__tree_node *r = &out->nodes[0];
        double diagonal = 0;
        for (int a = 0; a < 3; a++)
            diagonal += ((double)r->hi[a] - r->lo[a]) * ((double)r->hi[a] - r->lo[a]);
        discs_job job = {out, positions, triangles, DISC_SLACK * sqrt(diagonal)};
        sdf__parallel_for(out->node_count, 4096, 0, discs_range, &job);
    }
    if (bvh)
        rtcReleaseBVH(bvh);
    if (rc)
        sdf__tree_free(out);
    return rc;
}

void sdf__tree_free(sdf__tree *tree)
{
    free(tree->nodes);
    free(tree->discs);
    free(tree->prims);
    sdf__wide_free(&tree->wide);
    memset(tree, 0, sizeof *tree);
}
