/* sussman.h - the rounding paper's re-distancing solver: Sussman's re-initialization
 * d phi / dt = sign(f) (1 - |grad phi|) marched in time by eq. (1). */
#ifndef SDF_FIELD_SUSSMAN_H
#define SDF_FIELD_SUSSMAN_H

#include "field/redist.h"

/* The time step: CFL-bounded for the upwind scheme (see sussman.c). */
double sdf__sussman_dt(const sdf__field_grid *g);

/* The steps that make the solution exact up to `band` from the interface. */
int sdf__sussman_steps(const sdf__field_grid *g, double band);

/* March phi (set up by redist.c: interface nodes frozen, the band active, s->sign the
 * smoothed sign) for job->iterations steps, or as many as job->band needs. Uses s->work. */
int sdf__sussman_solve(const sdf__field_grid *g, float *phi, const sdf__redist_scratch *s,
                       const sdf__redist_job *job, sdf__redist_result *res);

#endif
