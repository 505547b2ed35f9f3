/* redist.h - re-distancing a sampled scalar field: the rounding paper's first-order
 * normalization as the initial condition, the interface nodes held at the distance of the
 * field's linear crossing, then |grad phi| = 1 solved outward up to a band by one of two
 * solvers (sussman.h, sweep.h). */
#ifndef SDF_FIELD_REDIST_H
#define SDF_FIELD_REDIST_H

#include "field/grid.h"
#include "sdf/sdf.h"

typedef struct sdf__redist_job {
    sdf_field_solver solver;
    double band;    /* distance up to which the result must be exact; INFINITY: the grid */
    int iterations; /* 0 = derived (see sdf_field_options) */
    /* Called between solver steps with the fraction of this re-distancing done; non-zero
     * cancels. May be NULL. */
    int (*tick)(void *ctx, double fraction);
    void *tick_ctx;
} sdf__redist_job;

typedef struct sdf__redist_result {
    int steps;       /* SUSSMAN time steps or SWEEP rounds taken */
    double reached;  /* distance up to which the result is exact (SUSSMAN: what its steps
                        reach; SWEEP: the band when converged, else 0) */
    double cap;      /* |values| beyond the band are clamped to this */
} sdf__redist_result;

/* Scratch of one re-distancing: g->nodes floats in work and sign (sign only for SUSSMAN),
 * g->nodes bytes in state. */
typedef struct sdf__redist_scratch {
    float *work;
    float *sign;
    uint8_t *state;
} sdf__redist_scratch;

/* Replace phi (g->nodes values, any field negative inside) by its signed distance within
 * job->band, clamped beyond. 0; SDF_EINVAL when phi has no zero crossing, SDF_ECANCELED
 * when tick asked to stop (phi's values are then meaningless). */
int sdf__field_redistance(const sdf__field_grid *g, float *phi, const sdf__redist_scratch *s,
                          const sdf__redist_job *job, sdf__redist_result *res);

#endif
