/* sweep.h - the second re-distancing solver: Zhao's fast sweeping method ("A fast sweeping
 * method for Eikonal equations", Math. Comp. 74, 2005) on the upwind (Godunov)
 * discretization of |grad phi| = 1 that eq. (1) of the rounding paper converges to. */
#ifndef SDF_FIELD_SWEEP_H
#define SDF_FIELD_SWEEP_H

#include "field/redist.h"

/* Solve for the unsigned distance in phi (set up by redist.c: interface nodes frozen at
 * their distance, the other active nodes at the cap, which they only ever lower). Rounds
 * of 8 sweeps: job->iterations of them, or until no node changes by more than 1e-4 of the
 * smallest spacing. */
int sdf__sweep_solve(const sdf__field_grid *g, float *phi, const uint8_t *state,
                     const sdf__redist_job *job, sdf__redist_result *res);

#endif
