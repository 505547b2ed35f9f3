/* workspace.h - a caller's scratch kept between batch calls (sdf_workspace, sdf.h).
 *
 * A batch call's large arrays (the Morton order and its keys, the points and answers in visit
 * order, a filtered call's per-point and per-block arrays, the per-node bests of a lattice that
 * the scan answers) used to be allocated and freed by every call, and their fresh pages faulted
 * in afresh each time, costly on virtual machines (the kernel clearing pages under the Morton
 * keys, the visit-order copies and the answers' scatter). A workspace keeps each array in a
 * slot of its own, grown when a call needs more, until the workspace is destroyed.
 *
 * The public entry points claim the workspace named in their options (sdf__ws_enter), so one
 * call at a time uses it; a call that finds it claimed runs as if it had none. Internal
 * calls made by a claiming call pass the same options on and use the workspace without
 * claiming it; the internal calls of bakes, which run on several threads, get none. */
#ifndef SDF_CORE_WORKSPACE_H
#define SDF_CORE_WORKSPACE_H

#include <stddef.h>

#include "sdf/sdf.h"

/* One slot per array that lives at the same time as another: a call's arrays never share a
 * slot with an array of an inner call that is still alive. */
typedef enum sdf__ws_slot {
    SDF__WS_ORDER,        /* points/points.c: the visit order */
    SDF__WS_MORTON_KEYS,  /* morton.c: the radix sort's keys, both halves */
    SDF__WS_VISIT_XYZ,    /* points/points.c: the points in visit order */
    SDF__WS_VISIT_OUT,    /* points/points.c: the answers in visit order */
    SDF__WS_FILTER_ORDER, /* filter.c: the points' visit order, alive across inner queries */
    SDF__WS_CENTRE_F,     /* filter.c: f and grad f at the points */
    SDF__WS_CENTRE_GRAD,
    SDF__WS_VOLUME_F,     /* filter.c: a smoothing mesh's f_s and grad f_s */
    SDF__WS_VOLUME_GRAD,
    SDF__WS_SAMPLE_P,     /* filter.c: a block's samples */
    SDF__WS_SAMPLE_F,
    SDF__WS_SAMPLE_GRAD,
    SDF__WS_SAMPLE_BOUND,
    SDF__WS_SAMPLE_SIGN,
    SDF__WS_SAMPLE_RUN,
    SDF__WS_SCAN_BESTS,   /* scan/scan.c: the zero order's per-worker bests */
    SDF__WS_SCAN_SAMPLES, /* scan/scan.c: the first order's per-worker sample bests */
    SDF__WS_SLOTS
} sdf__ws_slot;

/* A public call's options with its claim on their workspace. */
typedef struct sdf__ws_call {
    sdf_query_options opts; /* a copy without the workspace, when it could not be claimed */
    sdf_workspace *claimed;
} sdf__ws_call;

/* The options a public call runs with: `opts` itself when it names no workspace or its
 * workspace is now claimed for this call; otherwise a copy without one. NULL stays NULL. */
const sdf_query_options *sdf__ws_enter(const sdf_query_options *opts, sdf__ws_call *call);

/* Ends the call's claim, if it made one. */
void sdf__ws_leave(sdf__ws_call *call);

/* An array of at least `bytes` (huge-page backed from 2 MiB, core/bigmem.h): the
 * workspace's in `slot`, grown when smaller (its contents are not kept), or, without a
 * workspace, a fresh one. NULL when out of memory. */
void *sdf__ws_alloc(sdf_workspace *ws, sdf__ws_slot slot, size_t bytes);

/* Done with an array from sdf__ws_alloc: the workspace keeps it; without one it is freed. */
void sdf__ws_free(sdf_workspace *ws, void *p);

/* The bytes sdf_workspace_create allocates (scratch bounds of callers that make their own). */
size_t sdf__ws_create_bytes(void);

#endif
