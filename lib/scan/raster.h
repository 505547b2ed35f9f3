/* raster.h - the scan's state, shared by its two halves (private to scan/scan.c and
 * scan/raster.c).
 *
 * scan/scan.c sets a scan up and runs its calls; in each call every feature's region goes
 * to sdf__scan_region (scan/raster.c), the inner loop, which visits the call's nodes the
 * region holds and keeps each node's (zero order) or fine sample's (first order) nearest
 * feature so far in the worker's own arrays; scan.c then merges the workers' arrays and
 * finishes the nodes. */
#ifndef SDF_SCAN_RASTER_H
#define SDF_SCAN_RASTER_H

#include <stddef.h>
#include <stdint.h>

#include "geom/triangle.h" /* sdf__hit */
#include "core/parallel.h"  /* SDF__MAX_THREADS */
#include "scan/regions.h"
#include "scan/scan.h"

#define SDF__SCAN_MAX_W (2 * 4 + 1) /* first order: the fine grid's width, H <= 4 */
#define SDF__SCAN_MAX_SAMPLES (SDF__SCAN_MAX_W * SDF__SCAN_MAX_W * SDF__SCAN_MAX_W)
#define SDF__PENDING_VISITS 16 /* a region's node visits held back at a time (raster.c) */
#define SDF__POW3(w) ((size_t)(w) * (size_t)(w) * (size_t)(w))

struct sdf__scan {
    const sdf_mesh *mesh;
    sdf_query_options query;
    size_t dims[3];
    double origin[3], spacing[3];
    double *coord[3];          /* node coordinates per axis, as the float points sdf_query gets */
    sdf__features feat;
    double *coarse_coord[3];   /* the coarse lattice's node coordinates (feat.bound_coord) */
    uint32_t *order;           /* features in the mesh tree's order (scan.c, feature_order):
                                  neighbours in this order write to nearby nodes, so the
                                  per-node arrays stay in cache */
    float *coarse;             /* |f| on every COARSE_STEP-th node (scan.c; feat.bound) */
    sdf_workspace *ws;         /* where the per-worker bests live between calls (fresh pages
                                  cost): a lattice query's claimed workspace, else own_ws */
    sdf_workspace *own_ws;     /* the scan's own, for bakes (core/workspace.h) */
    float *zspan;              /* per feature its region's z-span (NAN: none), or NULL */
    int zspan_known;           /* zspan is filled (by the first call, which builds every
                                  region) */
    double inv_spacing[3];
    double index_slack[3];     /* float rounding of node coordinates, in nodes */
    double extent;             /* the scene's size: the scale of every rounding margin */
};

typedef struct sdf__fat_region sdf__fat_region;

/* Zero order: a node's best so far, in one place (the scan is bound by these loads: apart,
 * the three fields were three cache lines). */
typedef struct sdf__node_best {
    double d2;       /* smallest squared distance so far */
    uint32_t winner; /* its feature (ties: the lowest id, so the merge is deterministic) */
    int8_t sure;     /* with distances alone asked for: the winner's sign (+-1) when the node
                        is sure in its region (rows_range), else 0 */
} sdf__node_best;

typedef struct sdf__scan_call {
    sdf__scan *scan;
    size_t k0, k1;     /* the call's slices */
    size_t nodes;      /* in the call */
    sdf__node_best *best; /* per worker and node */
    int distances_only; /* sure nodes are marked (sdf__node_best.sure) */
    sdf__region *regions; /* per worker: the region being scanned */
    float *points;     /* per worker: a row of nodes */
    sdf__hit *hits;    /* per worker: their closest points */
    uint32_t *slow;    /* per worker: a row's nodes that take the exact test */
    float *slow_out;   /* per worker: their distances */
    int workers;
    sdf_query_result out;  /* zero order: the outputs, at the call's first node */
    /* First order (sdf__scan_samples): a node stands for its fine grid of W^3 samples. */
    int fine_w;            /* W = 2H + 1; 0 for zero order */
    double rho[3];         /* the fine grid's half-extent per axis: regions are dilated by it */
    double fine_offset[3][SDF__SCAN_MAX_W]; /* per axis, the W offsets of the fine grid */
    sdf__fat_region *fat;  /* per worker */
    float *sample_best;    /* per worker, node and sample: the smallest squared distance so
                              far, negative where its feature's pseudonormal says inside */
    float *merged;         /* per worker: MERGE_NODES nodes' signed distances */
    sdf__sample_fn consume;
    void *user;
    int consume_rc[SDF__MAX_THREADS];
} sdf__scan_call;

/* First order: what a region needs at every fine offset delta_j, once per region (the fine
 * grid is the same around every node). Samples sit at the float node plus delta_j, in
 * double: their distances are exact there, and within float rounding of the points a query
 * would be asked at. */
struct sdf__fat_region {
    double height[SDF__SCAN_MAX_SAMPLES]; /* face: dir . delta */
    double side[SDF__SCAN_MAX_SAMPLES];   /* sign_dir . delta */
    double delta[3][SDF__SCAN_MAX_SAMPLES];
    double delta2[SDF__SCAN_MAX_SAMPLES]; /* vertex: |delta|^2 */
    double cross[3][SDF__SCAN_MAX_SAMPLES]; /* edge: delta x dir */
    double plane_c[SDF__REGION_PLANES]; /* planes n . (p - origin) <= c */
    double plane_lo[SDF__REGION_PLANES], plane_hi[SDF__REGION_PLANES]; /* n . delta's range */
    /* n . delta_j of plane p, made the first time p straddles a node's fine grid. */
    uint8_t plane_ready[SDF__REGION_PLANES];
    double plane_delta[SDF__REGION_PLANES][SDF__SCAN_MAX_SAMPLES];
    /* Nodes whose candidates wait for their bests to arrive in the cache (raster.c). */
    size_t pending_node[SDF__PENDING_VISITS];
    float pending[SDF__PENDING_VISITS][SDF__SCAN_MAX_SAMPLES];
};

/* First order: the region's tables of the fine offsets, before its nodes are visited. */
void sdf__fat_prepare(const sdf__scan_call *st, const sdf__region *r, sdf__fat_region *fr);

/* Hand the region of `feature` to every node of the call it holds: zero order into `best`
 * (per node), first order into `best_samples` (per node and fine sample) with `fr`
 * prepared by sdf__fat_prepare. Both arrays are the worker's own, at the call's first node. */
void sdf__scan_region(const sdf__scan_call *st, const sdf__region *r, uint32_t feature,
                      sdf__node_best *best, float *best_samples, sdf__fat_region *fr);

#endif
