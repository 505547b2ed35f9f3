/* sdf.h - the public API of libsdf, the geometry core of sdfd.
 *
 * libsdf loads triangle meshes (OBJ, PLY, STL, OFF) into an immutable, shareable index and
 * answers batched point queries against it: exact unsigned and signed distance, closest
 * point, closest triangle with barycentric coordinates, and the distance gradient.
 *
 * Anything not declared here is not API.
 *
 * Conventions (see docs/design.md):
 *  - Every function that can fail returns int: 0 (SDF_OK) or a negative SDF_E* code.
 *    sdf_strerror() names it. Bad input never aborts the process.
 *  - Handles are opaque. A loaded sdf_mesh is immutable and may be queried from any number
 *    of threads at once; sdf_mesh_retain/sdf_mesh_release share it between owners.
 *  - Batch calls take caller-owned arrays; only *_create/_load functions allocate.
 *  - A zeroed options struct (or a NULL pointer to one) means defaults.
 *  - No global state: two meshes, or two threads, never interfere.
 *  - Embree, which builds the index, keeps about 200 bytes for every thread that has ever
 *    built one (sdf_mesh_load_*, sdf_mesh_create, and the first raycast-signed or
 *    single-traversal query of a mesh, which builds Embree's own scene) until the process
 *    exits. A long-running program builds on threads it keeps, not a new one each time.
 */
#ifndef SDF_SDF_H
#define SDF_SDF_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SDF_VERSION_MAJOR 0
#define SDF_VERSION_MINOR 1
#define SDF_VERSION_PATCH 0

/* ---------------------------------------------------------------------------------------
 * Errors. One table makes the enum, the names and the messages.
 * X(NAME, value, message)
 * Values -13..-19 are left to the layers built on the library, which extend this table
 * with codes of their own; a new code here takes -21 on.
 * ------------------------------------------------------------------------------------- */
#define SDF_ERRNO_MAP(X)                                                                  \
    X(EINVAL, -1, "invalid argument")                                                     \
    X(ENOMEM, -2, "out of memory")                                                        \
    X(EIO, -3, "cannot read file")                                                        \
    X(EFORMAT, -4, "unknown or unsupported file format")                                  \
    X(EPARSE, -5, "malformed data")                                                       \
    X(ETRUNC, -6, "truncated data")                                                       \
    X(ELIMIT, -7, "size limit exceeded")                                                  \
    X(EEMPTY, -8, "mesh has no triangles")                                                \
    X(ENONFINITE, -9, "coordinate is NaN, Inf or beyond +-1e18")                          \
    X(EINDEX, -10, "index out of range")                                                  \
    X(EBVH, -11, "BVH library (Embree) error")                                            \
    X(ENOTFOUND, -12, "not found")                                                        \
    X(ECANCELED, -20, "canceled")

typedef enum sdf_error {
    SDF_OK = 0,
#define SDF__ERRNO_ENUM(name, value, msg) SDF_##name = (value),
    SDF_ERRNO_MAP(SDF__ERRNO_ENUM)
#undef SDF__ERRNO_ENUM
} sdf_error;

/* A static, human-readable message for an error code ("unknown error" for others). */
const char *sdf_strerror(int err);
/* The code's name without prefix, e.g. "EPARSE"; "OK" for 0, "EUNKNOWN" for others. */
const char *sdf_errname(int err);

/* Where and why an input was rejected. Filled by functions that take an sdf_diag * (NULL
 * is allowed). `message` is self-contained, e.g. "OFF line 7: face 2 has vertex index 9,
 * but the file declares 8 vertices". */
typedef struct sdf_diag {
    int code;           /* the same code the function returned */
    long line;          /* 1-based line in a text format; 0 when not applicable */
    long long offset;   /* byte offset into the input; -1 when not applicable */
    char message[256];
} sdf_diag;

/* ---------------------------------------------------------------------------------------
 * Meshes
 * ------------------------------------------------------------------------------------- */
typedef enum sdf_format {
    SDF_FORMAT_AUTO = 0, /* from the file name's extension, else sniffed from the bytes */
    SDF_FORMAT_OBJ,
    SDF_FORMAT_PLY,
    SDF_FORMAT_STL,
    SDF_FORMAT_OFF,
} sdf_format;

/* Names of this header's enums, every pair alike: *_from_name matches a name whatever its
 * case and writes its value, or returns SDF_EINVAL (NULL or an unknown name; *out
 * unchanged); *_name gives a value's name in lower case, "?" for a value outside the enum. */

/* "auto", "obj", "ply", "stl", "off" -> format ("auto": from the extension or the bytes). */
int sdf_format_from_name(const char *name, sdf_format *out);
const char *sdf_format_name(sdf_format format);

typedef enum sdf_sign_method {
    SDF_SIGN_AUTO = 0,     /* pseudonormal for closed meshes that do not intersect
                              themselves, else winding */
    SDF_SIGN_PSEUDONORMAL, /* angle-weighted pseudonormals (Baerentzen & Aanaes 2005) */
    SDF_SIGN_WINDING,      /* fast generalized winding numbers (Barill et al. 2018) */
    SDF_SIGN_RAYCAST,      /* parity of ray crossings, majority over jittered rays */
    SDF_SIGN_NONE,         /* unsigned distance */
} sdf_sign_method;

/* "auto", "pseudonormal", "winding", "raycast", "none" -> method (as sdf_format_from_name). */
int sdf_sign_from_name(const char *name, sdf_sign_method *out);
const char *sdf_sign_name(sdf_sign_method method);

/* The largest coordinate magnitude of a mesh vertex or a query point (of a mesh or a volume:
 * one rule for both). Beyond it Embree's
 * builder and rays fail their own checks (its limit is 1.8e18), squared float distances
 * could overflow, and double precision no longer tells a small mesh's features apart. */
#define SDF_MAX_COORDINATE 1e18

#define SDF_DEFAULT_MAX_TRIANGLES ((size_t)1 << 24)      /* 16.7 M */
#define SDF_DEFAULT_MAX_FILE_BYTES ((size_t)1 << 31)     /* 2 GiB  */

typedef struct sdf_mesh_options {
    sdf_format format;      /* SDF_FORMAT_AUTO: by extension, else sniffed */
    size_t max_triangles;   /* after fan triangulation; 0 = SDF_DEFAULT_MAX_TRIANGLES */
    size_t max_file_bytes;  /* sdf_mesh_load_file only; 0 = SDF_DEFAULT_MAX_FILE_BYTES */
} sdf_mesh_options;

typedef struct sdf_mesh sdf_mesh;

/* What loading found out about a mesh. Counts are after welding exactly coincident
 * vertices; triangles keep the file's order (fan-triangulated polygons in place). */
#define SDF_MESH_WARNING_SIZE 160

typedef struct sdf_mesh_report {
    sdf_format format;           /* the format that was parsed (AUTO for in-memory arrays) */
    size_t input_vertices;       /* vertices as stored in the file */
    size_t vertices;             /* after welding */
    size_t triangles;
    float bbox_min[3], bbox_max[3];
    double diagonal;             /* |bbox_max - bbox_min| */
    int closed;                  /* every edge shared by exactly two consistently oriented triangles */
    int edge_manifold;           /* no edge shared by more than two triangles */
    int flipped;                 /* closed with negative volume: orientation was reversed */
    int self_intersecting;       /* closed, but two triangles sharing no vertex cross (only
                                    searched for closed meshes: it decides auto_sign) */
    size_t degenerate_triangles; /* zero area, or a repeated vertex */
    size_t boundary_edges;       /* edges with one triangle */
    size_t nonmanifold_edges;    /* edges with three or more triangles */
    size_t misoriented_edges;    /* two triangles traversing the edge in the same direction */
    double volume;               /* enclosed (signed) volume, after any flip */
    sdf_sign_method auto_sign;   /* what SDF_SIGN_AUTO resolves to for this mesh */
    size_t index_bytes;          /* memory of our BVH and the sign data (Embree's scene,
                                    made on the first raycast or single-traversal query,
                                    is not counted) */
    double build_seconds;        /* welding, topology, BVHs and sign data */
    size_t warnings;             /* things the parser accepted with doubt (e.g. a PLY header
                                    line with an unknown keyword, taken as a comment) */
    char warning[SDF_MESH_WARNING_SIZE]; /* the first of them, located like an error
                                    ("PLY line 3: ..."); "" when there is none */
} sdf_mesh_report;

/* Load a mesh file and build its index. On success *out holds a mesh with one reference.
 * On failure *out is NULL, the code is returned and `diag` (may be NULL) says where.
 * Thread-safe. */
int sdf_mesh_load_file(const char *path, const sdf_mesh_options *opts, sdf_mesh **out,
                       sdf_diag *diag);

/* As sdf_mesh_load_file, from `size` bytes at `data` (not retained). With
 * SDF_FORMAT_AUTO the format is sniffed from the bytes. */
int sdf_mesh_load_memory(const void *data, size_t size, const sdf_mesh_options *opts,
                         sdf_mesh **out, sdf_diag *diag);

/* Build a mesh from arrays: `vertex_count` xyz float triples and `triangle_count` index
 * triples (copied). Indices must be < vertex_count. */
int sdf_mesh_create(const float *vertices, size_t vertex_count, const uint32_t *triangles,
                    size_t triangle_count, const sdf_mesh_options *opts, sdf_mesh **out,
                    sdf_diag *diag);

/* Mesh files from arrays (`vertex_count` xyz float triples, `triangle_count` index
 * triples): binary little-endian PLY, OBJ, binary STL or OFF (SDF_FORMAT_AUTO is refused),
 * each of which sdf_mesh_load_memory reads back to the same floats. sdf_mesh_write_bound is
 * the bytes a buffer needs (0 for a bad format, or a size that overflows); sdf_mesh_write
 * fills `dst` (`cap` bytes, at least the bound) and returns the bytes written, or 0 when
 * the format is bad or cap is short. Indices must be < vertex_count. */
size_t sdf_mesh_write_bound(size_t vertex_count, size_t triangle_count, sdf_format format);
size_t sdf_mesh_write(const float *vertices, size_t vertex_count, const uint32_t *triangles,
                      size_t triangle_count, sdf_format format, void *dst, size_t cap);

/* The built-in demo mesh: a closed, manifold tube around a (2,3) torus knot (a trefoil),
 * generated in code, about 3 units across, 12,288 triangles. */
int sdf_mesh_create_demo(sdf_mesh **out);

/* Add a reference; returns `mesh`. Thread-safe. */
sdf_mesh *sdf_mesh_retain(sdf_mesh *mesh);
/* Drop a reference; the last one frees the mesh. NULL is a no-op. Thread-safe. */
void sdf_mesh_release(sdf_mesh *mesh);

/* Copy the mesh's report into *out. */
void sdf_mesh_get_report(const sdf_mesh *mesh, sdf_mesh_report *out);

/* The welded geometry the queries see, valid while the mesh lives: 3 floats per vertex,
 * 3 indices per triangle (counts in the report). Triangle ids returned by queries index
 * this array and follow the file's order. */
const float *sdf_mesh_vertices(const sdf_mesh *mesh);
const uint32_t *sdf_mesh_triangles(const sdf_mesh *mesh);

/* ---------------------------------------------------------------------------------------
 * Batched queries
 * ------------------------------------------------------------------------------------- */
typedef enum sdf_traversal {
    SDF_TRAVERSAL_PACKETS = 0, /* Morton-ordered packets of nearby points traverse the BVH
                                  together, each search seeded with a neighbour's bound */
    SDF_TRAVERSAL_SINGLE,      /* one independent query per point (the reference path) */
} sdf_traversal;

/* A caller's scratch kept between batch calls. sdf_query, sdf_query_filtered and
 * sdf_winding_numbers need large arrays for big batches (the points' Morton order, the points
 * and answers in visit order, a filtered call's samples: tens of MB for a million points).
 * Without a workspace each call allocates them and frees them at its end, and their fresh
 * pages fault in again next call (costly on virtual machines). Given one
 * in sdf_query_options.workspace, a call takes its arrays from it and leaves them there,
 * grown to the largest call's needs, for the next (a lattice that the scan answers keeps its
 * per-node arrays there too). Answers are the same with or without one.
 * A workspace serves one call at a time: a call that finds it in use by another runs as if
 * it had none. Bakes (sdf_volume_bake) ignore it. */
typedef struct sdf_workspace sdf_workspace;

/* A new, empty workspace; SDF_ENOMEM, or SDF_EINVAL for a NULL `out`. */
int sdf_workspace_create(sdf_workspace **out);
/* Frees the workspace and all it holds; NULL is a no-op. Not while a call uses it. */
void sdf_workspace_destroy(sdf_workspace *ws);
/* The bytes the workspace holds now (0 for NULL): each of its arrays at the largest size a
 * call it served needed. Read it between calls. */
size_t sdf_workspace_bytes(const sdf_workspace *ws);

typedef struct sdf_query_options {
    sdf_sign_method sign;    /* SDF_SIGN_AUTO by default */
    int threads;             /* worker threads; 0 = all online CPUs */
    size_t point_stride;     /* bytes between consecutive points; 0 = 12 (packed xyz) */
    sdf_traversal traversal; /* PACKETS by default; both give the same distances (exact ties
                                between equally close triangles may name either one) */
    sdf_workspace *workspace; /* NULL by default: each call allocates its own scratch */
} sdf_query_options;

/* Caller-owned outputs of sdf_query; any pointer may be NULL when not wanted. */
typedef struct sdf_query_result {
    float *distance;     /* [n] signed distance, negative inside (unsigned with SIGN_NONE) */
    float *gradient;     /* [3n] unit gradient of `distance`: sign * (p - c) / |p - c|; on the
                            surface, the closest feature's pseudonormal */
    float *closest;      /* [3n] closest point on the mesh */
    uint32_t *triangle;  /* [n] id of the triangle holding the closest point */
    float *barycentric;  /* [3n] weights (w0, w1, w2) of that triangle's vertices 0, 1, 2 at
                            the closest point: c = w0 v0 + w1 v1 + w2 v2, summing to 1. Open3D's
                            primitive_uvs are (u, v) = (w1, w2); libigl's barycentric
                            coordinates of c in (v0, v1, v2) are (w0, w1, w2) */
    size_t bad_index;    /* out: the first bad point when SDF_ENONFINITE is returned */
    float *normal;       /* [3n] that triangle's unit normal, (v1 - v0) x (v2 - v0)
                            normalized, with the mesh's orientation (outward on closed meshes,
                            which are reoriented if inside out); Open3D's primitive_normals.
                            (0, 0, 0) for a degenerate triangle. sdf_query only */
} sdf_query_result;

/* Answer `count` point queries. `points` holds xyz float triples `point_stride` bytes apart.
 * Returns SDF_ENONFINITE (and sets out->bad_index) if any coordinate is NaN, Inf or beyond
 * +-SDF_MAX_COORDINATE, before writing any output; SDF_EINVAL for a bad argument.
 * Results do not depend on the thread count. Thread-safe on a shared mesh. */
int sdf_query(const sdf_mesh *mesh, const float *points, size_t count,
              const sdf_query_options *opts, sdf_query_result *out);

/* Generalized winding number (Jacobson et al. 2013) at each point, evaluated
 * hierarchically (Barill et al. 2018): ~1 inside, ~0 outside a closed mesh; fractional
 * near holes. Same argument rules as sdf_query; writes `count` floats to `winding`. With
 * SDF_TRAVERSAL_PACKETS (the default) nearby points share one traversal; the values are the
 * same as with SDF_TRAVERSAL_SINGLE. */
int sdf_winding_numbers(const sdf_mesh *mesh, const float *points, size_t count,
                        const sdf_query_options *opts, float *winding, size_t *bad_index);

/* ---------------------------------------------------------------------------------------
 * Convolution-filtered signed distance (Sanchez et al., "Convolution filtering of
 * continuous signed distance fields for polygonal meshes"; docs/filtered.md)
 *
 *   g(p) = (1/n) sum_i f(p - s_i h(p))                      (eq. 10, samples s_i ~ w)
 *   h(p) = 3 r^2 - 2 r^3,  r = min(|f(p)| / f_c, 1)         (eq. 4: g = f on the surface)
 * ------------------------------------------------------------------------------------- */
typedef enum sdf_kernel {
    SDF_KERNEL_GAUSSIAN = 0, /* w(u) = (a/pi)^(3/2) exp(-a |u|^2), sampled by Box-Muller */
    SDF_KERNEL_BUMP,         /* w(u) = C exp(1/(|u/b|^2 - 1)) inside |u| < b (eqs. 5-6),
                                sampled by rejection from the uniform cube [-b, b]^3 */
} sdf_kernel;

/* Localized smoothing (sec. 6.1): only inside a smoothing volume is the field filtered, with
 * the kernel size driven by the depth into the volume instead of eq. (4):
 *   h_m(p) = smoothstep(min(-f_s(p) / s_d, 1)) * s_r  where f_s(p) < 0 (inside), else 0,
 * f_s the volume's signed distance, smoothstep(t) = 3t^2 - 2t^3. Outside the volume g = f
 * exactly; at the boundary h_m = 0, so g is continuous; inside, the surface itself is smoothed
 * (the kernel does not vanish there: this is shape editing). */
typedef enum sdf_volume_shape {
    SDF_VOLUME_NONE = 0, /* no volume: eq. (4) everywhere */
    SDF_VOLUME_SPHERE,
    SDF_VOLUME_BOX,
    SDF_VOLUME_MESH,     /* another mesh; inside where its signed distance (auto sign) < 0 */
} sdf_volume_shape;

typedef struct sdf_smoothing_volume {
    sdf_volume_shape shape;
    double center[3], radius; /* SPHERE */
    double lo[3], hi[3];      /* BOX: opposite corners, lo < hi on every axis */
    const sdf_mesh *mesh;     /* MESH: must outlive the call */
    double depth;             /* s_d, a length; 0 = f_c */
    double scale;             /* s_r, the largest kernel size as a multiple of the kernel's
                                 width (sigma or b); 0 = 1 */
} sdf_smoothing_volume;

typedef struct sdf_filter_options {
    sdf_kernel kernel;
    double cap;             /* f_c; 0 = 0.02 x the mesh's bounding-box diagonal */
    double a;               /* Gaussian parameter a; 0 = 8 / f_c^2 (sigma = f_c / 4) */
    double b;               /* bump width b; 0 = 8 f_c / 9, the largest eq. (7) allows */
    int samples;            /* n, 1..SDF_FILTER_MAX_SAMPLES; 0 = SDF_FILTER_DEFAULT_SAMPLES
                               (N_max when adaptive) */
    int min_samples;        /* adaptive quality (sec. 5.2): N_min, 1..samples; 0 = off, every
                               point gets `samples`. Then a 3^3 stencil first detects the
                               medial axis and n_a = N_min + (n_medial + n_distance) / 2 *
                               (N_max - N_min) samples are used, the last one weighted by the
                               fractional part of n_a */
    double medial;          /* adaptive: the stencil response |mean - centre| / spacing at
                               which n_medial reaches 1; 0 = 0.2 */
    int grid;               /* 1: the weighted regular 3^3 grid of eq. (9) instead (27
                               samples at 0, +-s per axis, s = sigma or b/2, weights w(s_i)) */
    int unsigned_integrand; /* 1: g = sign(f(p)) (1/n) sum |f(p - s_i h)|: no extra zero sets */
    int allow_wide_bump;    /* 1: accept b > 8 f_c / 9 (may create extra zero level sets) */
    int sample_gradient;    /* 1: the gradient output is the raw field's gradient averaged over
                               the samples, sum w_i grad f(x_i) (the unsigned integrand: of
                               |f|, times sign f(p)), without the terms for how h and n_a vary
                               with p; 0: the analytic gradient of g. The value is the same */
    uint64_t seed;          /* the sample set is drawn once from this seed */
    sdf_smoothing_volume smooth; /* localized smoothing; shape NONE (default) = everywhere */
} sdf_filter_options;

#define SDF_FILTER_MAX_SAMPLES 4096
#define SDF_FILTER_DEFAULT_SAMPLES 64

/* The filtered field g and its analytic gradient (or, with filter->sample_gradient, the
 * samples' mean gradient) at `count` points (out->distance, out->gradient; the other outputs
 * must be NULL). Parameters left 0 take the defaults above;
 * a bad one fails with SDF_EINVAL and a message in *diag (which states the bound for a bump
 * that is too wide). The same points, options and seed give the same floats on any thread
 * count. Costs n + 1 signed-distance queries per point (n + 27 when adaptive), evaluated as
 * packets. With count 0 it only checks the options, allocating nothing for samples. */
int sdf_query_filtered(const sdf_mesh *mesh, const float *points, size_t count,
                       const sdf_query_options *opts, const sdf_filter_options *filter,
                       sdf_query_result *out, sdf_diag *diag);

/* ---------------------------------------------------------------------------------------
 * Distance volumes (docs/volumes.md): the signed distance baked on a regular grid of nodes,
 * either one value per node (zero order) or a first-order Taylor distance field (TDF; Ban &
 * Valasek, "First Order Signed Distance Fields"): per node the plane a x + b y + c z + d in
 * the global power basis (eq. 2) fitted to distances on a fine (2H+1)^3 grid around the node
 * (Algorithm 1). Node (i, j, k) lies at origin + (i sx, j sy, k sz); data is stored x fastest,
 * then y, then z: node index (k M + j) N + i.
 * ------------------------------------------------------------------------------------- */
typedef enum sdf_volume_encoding {
    SDF_ENCODING_FLOAT32 = 0, /* order 0: 1 float per node; order 1: 4 floats a, b, c, d */
    SDF_ENCODING_PACKED32,    /* order 1 only: one uint32 per node (sec. 5.3): bits 0-9 and
                                 10-19 the octahedral normal (a, b, c) as 10-bit snorm, bits
                                 20-31 the plane's value at the node as 12-bit snorm over
                                 packed_center +- packed_range; d = value - (a, b, c) . node */
} sdf_volume_encoding;

/* "float32", "packed32" -> encoding (as sdf_format_from_name). */
int sdf_encoding_from_name(const char *name, sdf_volume_encoding *out);
const char *sdf_encoding_name(sdf_volume_encoding encoding);

#define SDF_VOLUME_MAX_DIM 4096            /* nodes along one axis */
#define SDF_VOLUME_MAX_NODES ((size_t)1 << 30)

/* Step 6 of Algorithm 1 (first order): what the fitted plane is divided by |(a, b, c)| in. */
typedef enum sdf_tdf_normalize {
    SDF_NORMALIZE_PLANE = 0, /* all four coefficients, as the paper does: the plane keeps its
                                zero set, but its value at the node grows where the fitted
                                gradient is short (near the medial axis) */
    SDF_NORMALIZE_GRADIENT,  /* (a, b, c) only: the plane keeps the fitted value at its node;
                                1.4-5x more accurate on our meshes (docs/volumes.md) */
} sdf_tdf_normalize;

typedef struct sdf_volume_info {
    size_t dims[3];          /* N, M, K: nodes along x, y, z, each 2..SDF_VOLUME_MAX_DIM */
    double origin[3];        /* position of node (0, 0, 0) */
    double spacing[3];       /* distance between neighbouring nodes along x, y, z, > 0 */
    int order;               /* 0 or 1 */
    sdf_volume_encoding encoding;
    double packed_center;    /* PACKED32: node values are packed_center + q / 2047 *
                                packed_range, q the 12-bit snorm; both 0 for FLOAT32 */
    double packed_range;
    int fine_half;           /* order 1: H of the (2H+1)^3 fitting grid; 0 for order 0 */
    double fine_spacing;     /* order 1: the fitting grid's spacing in cells (Delta) */
    sdf_tdf_normalize normalize; /* order 1: step 6 as baked */
    int filtered;            /* 1: baked from the convolution-filtered field */
} sdf_volume_info;

/* "plane", "gradient" -> normalisation (as sdf_format_from_name). */
int sdf_normalize_from_name(const char *name, sdf_tdf_normalize *out);
const char *sdf_normalize_name(sdf_tdf_normalize normalize);

/* 32-bit words per node (1 for order 0 and for PACKED32, 4 for first-order FLOAT32). */
int sdf_volume_channels(const sdf_volume_info *info);

typedef struct sdf_volume sdf_volume;

typedef struct sdf_bake_options {
    double lo[3], hi[3];      /* the corner nodes; all zero = the mesh's box grown by `margin`
                                 on every side. lo < hi on every axis */
    double margin;            /* default bounds only: a length; 0 = 5 % of the diagonal */
    size_t dims[3];           /* nodes per axis; 0 = 64 */
    int order;                /* 0 (default) or 1 */
    int fine_half;            /* order 1: H, 1..4; 0 = 1 (a 3^3 fitting grid) */
    double fine_spacing;      /* order 1: Delta in cells, (0, 0.5]; 0 = 0.1 */
    sdf_tdf_normalize normalize; /* order 1: PLANE (the paper's step 6) by default */
    sdf_volume_encoding encoding;
    const sdf_filter_options *filter; /* NULL: the raw signed distance; else the filtered one */
    sdf_query_options query;  /* sign and threads (point_stride and traversal are ignored) */
    /* Called from the calling thread after each slab of nodes with the fraction done
     * (0..1]; a non-zero return cancels the bake (SDF_ECANCELED). May be NULL. */
    int (*progress)(void *user, double fraction);
    void *user;
} sdf_bake_options;

/* Bake a volume of `mesh`. SDF_EINVAL (with a message in *diag) for a bad option,
 * SDF_ELIMIT for more than SDF_VOLUME_MAX_NODES nodes, SDF_ECANCELED when `progress` asked
 * to stop, SDF_ENOMEM. The same options give the same floats on any thread count. */
int sdf_volume_bake(const sdf_mesh *mesh, const sdf_bake_options *opts, sdf_volume **out,
                    sdf_diag *diag);

/* Check `opts` for `mesh` as sdf_volume_bake would (every message the same) and describe
 * the volume it would make (packed_range and packed_center are only known after baking),
 * without baking. */
int sdf_volume_plan(const sdf_mesh *mesh, const sdf_bake_options *opts, sdf_volume_info *planned,
                    sdf_diag *diag);

/* An upper bound of the bytes sdf_volume_bake(mesh, opts) allocates besides the volume it
 * returns (sdf_volume_channels x 4 bytes a node): its working arrays, the first order's
 * planes, and for the scan the mesh's adjacency and a coarse lattice (docs/volumes.md). For
 * callers that budget memory; checks `opts` as sdf_volume_plan does. */
int sdf_volume_bake_scratch(const sdf_mesh *mesh, const sdf_bake_options *opts, size_t *bytes,
                            sdf_diag *diag);

/* A volume from its description and node data (copied; sdf_volume_channels(info) 32-bit
 * words per node, float or uint32 by the encoding). Checks the description (dims 2..
 * SDF_VOLUME_MAX_DIM, spacing > 0, every node's coordinate and 1 / spacing finite, ...):
 * SDF_EINVAL with the reason; non-finite floats are SDF_ENONFINITE. */
int sdf_volume_create(const sdf_volume_info *info, const void *data, sdf_volume **out,
                      sdf_diag *diag);

void sdf_volume_destroy(sdf_volume *volume); /* NULL is a no-op */
void sdf_volume_get_info(const sdf_volume *volume, sdf_volume_info *out);
const void *sdf_volume_data(const sdf_volume *volume); /* the node words, see above */
size_t sdf_volume_data_bytes(const sdf_volume *volume);

typedef enum sdf_volume_filter {
    SDF_VOLUME_DEFAULT = 0,   /* the most accurate reconstruction of the volume's order:
                                 TRILINEAR for order 0, HERMITE for order 1 */
    SDF_VOLUME_NEAREST,       /* the nearest node's value (order 0) or plane at the point */
    SDF_VOLUME_TRILINEAR,     /* order 0: trilinear interpolation of the node values; order 1:
                                 of the 8 nodes' coefficients, the plane then evaluated at
                                 the point (exact in the power basis, sec. 3) */
    SDF_VOLUME_HERMITE,       /* order 1 only: tricubic Hermite of the nodes' values and
                                 gradients, cross derivatives from central differences of
                                 the neighbours' gradients, each value limited by the
                                 neighbours' closest points (docs/volumes.md); C1 */
} sdf_volume_filter;

/* "default", "nearest", "trilinear", "hermite" -> filter (as sdf_format_from_name). */
int sdf_volume_filter_from_name(const char *name, sdf_volume_filter *out);
const char *sdf_volume_filter_name(sdf_volume_filter filter);

/* The volume's field at `count` points (packed xyz): value[count] and, if not NULL,
 * gradient[3 count] - the exact gradient of the reconstructed field (zero order nearest:
 * central differences of the node values around the nearest node). Outside the volume the
 * node lookup clamps to the boundary (as a GPU sampler's clamp-to-edge): zero order
 * continues the boundary values, first order extends the boundary planes (hermite: the
 * boundary's values and derivatives) linearly. SDF_EINVAL for an unknown filter or HERMITE
 * on a zero-order volume; SDF_ENONFINITE (and *bad_index) for a coordinate that is NaN, Inf
 * or beyond +-SDF_MAX_COORDINATE (as sdf_query), before writing anything. Large batches run on all CPUs (the same floats either way).
 * Thread-safe. */
int sdf_volume_eval(const sdf_volume *volume, const float *points, size_t count,
                    sdf_volume_filter filter, float *value, float *gradient, size_t *bad_index);

/* Volume files (docs/volumes.md):
 *  EXR: OpenEXR, one scanline image N wide and M K high (z-slices stacked), ZIP-compressed
 *       FLOAT channels "d" (order 0) or "a" "b" "c" "d" (order 1), or one UINT channel
 *       "packed"; attributes sdf.dims (v3i), sdf.origin, sdf.spacing (v3d), sdf.order (int),
 *       sdf.encoding (string), sdf.packedCenter, sdf.packedRange (double), sdf.fineHalf (int),
 *       sdf.fineSpacing (double), sdf.normalize (string), sdf.filtered (int).
 *  NPY: float32 (K, M, N) or (K, M, N, 4); uint32 (K, M, N) for PACKED32.
 *  RAW: the node words alone, little-endian (sdf_volume_describe_json gives the metadata). */
typedef enum sdf_volume_file { SDF_VOLUME_EXR = 0, SDF_VOLUME_NPY, SDF_VOLUME_RAW } sdf_volume_file;

/* "exr", "npy", "raw" -> file type (as sdf_format_from_name). */
int sdf_volume_file_from_name(const char *name, sdf_volume_file *out);
const char *sdf_volume_file_name(sdf_volume_file type);

/* Encode the volume as a file in a new malloc'ed buffer (*data, *size; release with free). */
int sdf_volume_save_memory(const sdf_volume *volume, sdf_volume_file type, void **data,
                           size_t *size, sdf_diag *diag);
int sdf_volume_save_file(const sdf_volume *volume, sdf_volume_file type, const char *path,
                         sdf_diag *diag);

/* The .npy header of the volume (the file is this header, then sdf_volume_data's bytes):
 * its length, or a negative SDF_E* code (512 bytes of dst always suffice). */
long sdf_volume_npy_header(const sdf_volume *volume, char *dst, size_t cap);

/* Read an EXR volume written by sdf_volume_save_* (`size` bytes; every length and
 * attribute is checked). */
int sdf_volume_load_exr_memory(const void *data, size_t size, sdf_volume **out, sdf_diag *diag);
int sdf_volume_load_exr_file(const char *path, sdf_volume **out, sdf_diag *diag);

/* The volume's description as one JSON object into dst (cap bytes, 1024 always suffice).
 * Returns its length, or SDF_ELIMIT when it does not fit. */
long sdf_volume_describe_json(const sdf_volume *volume, char *dst, size_t cap);

/* ---------------------------------------------------------------------------------------
 * Field operations (docs/volumes.md, "Field operations"; the rounding paper, docs/
 * references.md): new volumes from a zero-order FLOAT32 volume holding any scalar field whose
 * zero set is a surface (negative inside). First-order and PACKED32 volumes are refused
 * (SDF_EINVAL). sdfd's sign convention throughout: negative inside, so
 *  REDISTANCE r: the signed distance to the zero set, accurate up to r from it (0: the whole
 *                grid); the paper's first-order normalization, then re-initialization
 *  OFFSET r:     phi - r (re-distanced first): the surface moves outward by r (r < 0: inward)
 *  ROUND r:      erode by r, re-distance, dilate by r (an opening): convex edges and corners
 *                get radius r; r > 0
 *  FILLET r:     dilate, re-distance, erode (a closing): concave ones get radius r; r > 0
 *  SMOOTH r:     ROUND r then FILLET r, its two consecutive dilations merged: three
 *                re-distancings; r > 0
 * A result is a signed distance up to sdf_field_options.band from its surface; farther
 * values keep their sign and are clamped to the distance the last re-distancing computed.
 * X(NAME, value, name)
 * ------------------------------------------------------------------------------------- */
#define SDF_FIELD_OP_MAP(X)                                                               \
    X(REDISTANCE, 0, "redistance")                                                        \
    X(OFFSET, 1, "offset")                                                                \
    X(ROUND, 2, "round")                                                                  \
    X(FILLET, 3, "fillet")                                                                \
    X(SMOOTH, 4, "smooth")

typedef enum sdf_field_op_kind {
#define SDF__FIELD_OP_ENUM(name, value, str) SDF_FIELD_##name = (value),
    SDF_FIELD_OP_MAP(SDF__FIELD_OP_ENUM)
#undef SDF__FIELD_OP_ENUM
} sdf_field_op_kind;

/* "redistance", "offset", "round", "fillet", "smooth" -> kind; SDF_EINVAL otherwise. */
int sdf_field_op_from_name(const char *name, sdf_field_op_kind *out);
const char *sdf_field_op_name(sdf_field_op_kind kind); /* "unknown" for others */

/* The re-distancing solver: both solve |grad phi| = 1 with the same upwind (Godunov)
 * discretization and the same interface nodes (held at the distance of the field's linear
 * crossing), so they converge to the same values. */
#define SDF_FIELD_SOLVER_MAP(X)                                                           \
    X(SUSSMAN, 0, "sussman") /* the paper's eq. (1): Sussman's re-initialization PDE,      \
                                forward Euler, CFL-bounded steps, smoothed sign */        \
    X(SWEEP, 1, "sweep")     /* Zhao's fast sweeping: Gauss-Seidel in 8 orders */        \
    X(EXACT, 2, "exact")     /* the zero set extracted (marching cubes on the field's      \
                                linear crossings), then each node of the band its exact    \
                                distance to it (docs/volumes.md); iterations ignored */

typedef enum sdf_field_solver {
#define SDF__FIELD_SOLVER_ENUM(name, value, str) SDF_FIELD_##name = (value),
    SDF_FIELD_SOLVER_MAP(SDF__FIELD_SOLVER_ENUM)
#undef SDF__FIELD_SOLVER_ENUM
} sdf_field_solver;

/* "sussman", "sweep", "exact" -> solver; SDF_EINVAL otherwise. */
int sdf_field_solver_from_name(const char *name, sdf_field_solver *out);
const char *sdf_field_solver_name(sdf_field_solver solver); /* "unknown" for others */

typedef struct sdf_field_op {
    sdf_field_op_kind kind;
    float r; /* a length in the volume's units; finite, |r| below the grid's diagonal */
} sdf_field_op;

#define SDF_FIELD_MAX_OPS 64

typedef struct sdf_field_options {
    sdf_field_solver solver;
    int iterations;  /* per re-distancing: SUSSMAN time steps, SWEEP rounds of 8 sweeps;
                        0 = derived (SUSSMAN: enough steps to reach the needed distance;
                        SWEEP: until no node changes by more than 1e-4 cells) */
    double band;     /* distance from the result's surface up to which it must be exact;
                        0 = 4 of the smallest spacing */
    int threads;     /* 0 = all CPUs; the result does not depend on it */
    int strict;      /* non-zero: a caveat (below) fails the call with SDF_EINVAL */
    /* Called from the calling thread between solver steps with the fraction done (0..1];
     * a non-zero return cancels (SDF_ECANCELED). May be NULL. */
    int (*progress)(void *user, double fraction);
    void *user;
} sdf_field_options;

/* The paper's validity caveats, detected on the volume at hand (sdf_volume_apply_ops). */
#define SDF_FIELD_CAVEAT_BAND 1u     /* an iterations override left the re-distanced band
                                        narrower than the following offset needs (SUSSMAN), or
                                        the sweeps had not converged (SWEEP) */
#define SDF_FIELD_CAVEAT_GRID 2u     /* a dilation brought the surface, or the band it must be
                                        exact in, to the grid's boundary: the grid cuts it */
#define SDF_FIELD_CAVEAT_TOPOLOGY 4u /* an offset changed how many connected parts the solid
                                        or its outside has: it crossed the medial axis (a part
                                        thinner than 2r vanished, a gap narrower than 2r
                                        closed), so the result is not a rounding/filleting */

/* Apply `count` (1..SDF_FIELD_MAX_OPS) operations in order to `in` (a zero-order FLOAT32
 * volume) into a new zero-order FLOAT32 volume of the same grid (*out). SDF_EINVAL with a
 * message for a bad option or op, a first-order or packed volume, a field without a zero
 * crossing, or an operation that leaves no surface (an erosion removing the whole solid);
 * SDF_ENONFINITE for a NaN or Inf node value; SDF_ECANCELED; SDF_ENOMEM (its scratch: 9
 * bytes a node, 4 more for SUSSMAN, 4 more for a chain with an offset; EXACT: 5 more, the
 * surface's mesh and index, and up to 48 MiB of queries). On success *caveats (may be NULL) holds the SDF_FIELD_CAVEAT_* bits that
 * fired and diag's message describes the first of them (code 0; "success" when none); with
 * opts->strict a caveat is an SDF_EINVAL error instead. */
int sdf_volume_apply_ops(const sdf_volume *in, const sdf_field_op *ops, size_t count,
                         const sdf_field_options *opts, sdf_volume **out, unsigned *caveats,
                         sdf_diag *diag);

/* ---------------------------------------------------------------------------------------
 * Surfaces of volumes (docs/volumes.md, "Meshes from volumes"): the iso-surface of a volume's
 * node values as triangles, by marching cubes with one rule on every face (the asymptotic
 * decider), so that neighbouring cells agree, or by its dual (SDF_EXTRACT_DUAL): the surface is closed and edge-manifold where
 * it stays inside the grid, every triangle's normal points to increasing values (outward of
 * a signed distance's solid: the enclosed volume is positive), and no triangle repeats a
 * vertex. A first-order volume's node values are its planes' values at the nodes.
 * ------------------------------------------------------------------------------------- */
typedef enum sdf_extract_method {
    SDF_EXTRACT_AUTO = 0,          /* DUAL for a first-order volume, else MARCHING_CUBES */
    SDF_EXTRACT_MARCHING_CUBES,    /* vertices on the grid's edges: sharp edges chamfered */
    SDF_EXTRACT_DUAL,              /* dual contouring with the nodes' gradients as Hermite
                                      data (first order: the planes'; zero order: central
                                      differences of the values): a vertex per sheet of each
                                      cell where their quadratic error is least, clamped to
                                      the cell, so sharp edges and corners come back; the same
                                      topology guarantees, but triangles may be slivers or
                                      fold */
} sdf_extract_method;

/* "auto", "marching_cubes", "dual_contouring" -> method (as sdf_format_from_name). */
int sdf_extract_method_from_name(const char *name, sdf_extract_method *out);
const char *sdf_extract_method_name(sdf_extract_method method);

typedef struct sdf_extract_options {
    double iso;   /* the value whose surface is taken; finite */
    int cap;      /* 0: the surface ends open where it leaves the grid; 1: closed there by
                     caps on the grid's boundary (the outside of the grid counts as outside) */
    int threads;  /* 0 = all CPUs; the result does not depend on it */
    sdf_extract_method method;
} sdf_extract_options;

typedef struct sdf_surface sdf_surface;

/* The surface of `volume` at opts->iso (NULL options: iso 0, no caps, AUTO). Marching
 * cubes' vertices lie on the grid's edges, at least 1/1000 of a cell from the nodes (a node's
 * value equal to iso counts as outside); DUAL's inside the cells. The same volume and options give the same arrays on any thread count. A
 * volume whose values never cross iso gives a surface of no triangles. SDF_EINVAL (a
 * non-finite iso, an unknown method), SDF_ELIMIT (2^32 vertices or more), SDF_ENOMEM. */
int sdf_volume_extract(const sdf_volume *volume, const sdf_extract_options *opts,
                       sdf_surface **out, sdf_diag *diag);

/* The surface's arrays, valid while it lives: 3 floats a vertex (world coordinates), 3
 * indices a triangle, counter-clockwise seen from outside. */
const float *sdf_surface_vertices(const sdf_surface *surface, size_t *count);
const uint32_t *sdf_surface_triangles(const sdf_surface *surface, size_t *count);

/* The surface as a mesh that answers queries (sdf_mesh_create on its arrays). */
int sdf_surface_to_mesh(const sdf_surface *surface, const sdf_mesh_options *opts,
                        sdf_mesh **out, sdf_diag *diag);

void sdf_surface_destroy(sdf_surface *surface); /* NULL is a no-op */

/* ---------------------------------------------------------------------------------------
 * NumPy .npy arrays (version 1.0/2.0/3.0 headers; little-endian float32 or float64; C order)
 * ------------------------------------------------------------------------------------- */
typedef enum sdf_npy_dtype { SDF_NPY_F32 = 4, SDF_NPY_F64 = 8 } sdf_npy_dtype;

#define SDF_NPY_MAX_DIMS 4

typedef struct sdf_npy_info {
    sdf_npy_dtype dtype;  /* floats; 0 for integers (sdf_npy_parse_numeric) */
    char kind;            /* 'f' float, 'i' signed or 'u' unsigned integer */
    size_t itemsize;      /* bytes per element: 1, 2, 4 or 8 */
    int ndim;
    size_t shape[SDF_NPY_MAX_DIMS];
    size_t data_offset; /* bytes before the array data */
    size_t data_bytes;  /* product(shape) * dtype size */
} sdf_npy_info;

/* Parse and check a complete .npy file held in `size` bytes: the header and that exactly
 * data_bytes follow it. Big-endian, Fortran-order, object or other dtypes are refused
 * (SDF_EFORMAT); a short file is SDF_ETRUNC; `diag` says where. */
int sdf_npy_parse(const void *data, size_t size, sdf_npy_info *info, sdf_diag *diag);
/* As sdf_npy_parse, and little-endian integers of 1, 2, 4 or 8 bytes too ('<i8', '<u4',
 * '|u1', ...: `kind` and `itemsize` say which; `dtype` is 0 for them). */
int sdf_npy_parse_numeric(const void *data, size_t size, sdf_npy_info *info, sdf_diag *diag);

/* Write a version 1.0 header for a little-endian float32 C-order array of `ndim` (1..4)
 * dimensions into `dst` (`cap` bytes). Returns the header's length (a multiple of 64),
 * or a negative SDF_E* code (SDF_ELIMIT if `cap` is too small; 128 bytes always suffice). */
long sdf_npy_write_header(char *dst, size_t cap, int ndim, const size_t *shape);

/* The same with any dtype description, written verbatim, e.g. a structured dtype
 * "[('distance', '<f4'), ('triangle', '<u4')]" (at most 192 characters; 512 bytes of
 * `dst` always suffice). */
long sdf_npy_write_header_descr(char *dst, size_t cap, const char *descr, int ndim,
                                const size_t *shape);

#ifdef __cplusplus
}
#endif
#endif /* SDF_SDF_H */
