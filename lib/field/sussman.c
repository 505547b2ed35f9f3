/* sussman.c - eq. (1) of the rounding paper: forward Euler in time, first-order upwind
 * differences in space,
 *   phi^{n+1} = phi^n - dt sign(f) (H(D+x, D-x, D+y, D-y, D+z, D-z) - 1),
 * with the Godunov Hamiltonian H below eq. (1) (for sign(f) >= 0 the gradient from the
 * smaller neighbours, max((D+^-)^2, (D-^+)^2) per axis; for sign(f) < 0 the mirror) and the
 * paper's smoothed sign f / sqrt(f^2 + eps^2), eps = the smallest spacing (redist.c).
 * Jacobi steps (every node from the previous step's values) make the result independent of
 * the thread count; only rows holding nodes to update are visited. On the grid's faces the missing neighbour's difference is 0 (the field
 * is continued by its boundary value).
 *
 * Time step: the upwind scheme is monotone (hence stable) while dt sum_a |dH/dp_a| / h_a
 * <= 1; |dH/dp| is a unit vector scaled by |sign(f)| <= 1, so by Cauchy-Schwarz the sum is
 * at most sqrt(sum_a 1 / h_a^2). dt takes CFL = 0.8 of that bound.
 *
 * Steps: characteristics carry the distance outward at unit speed, so after n steps the
 * nodes within n dt of the interface hold their distance ("only up to the distance r" in
 * the paper's Offsetting section); the derived count adds two of the largest spacings for
 * the nodes next to the interface to settle. */
#include "field/sussman.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/parallel.h"

#define CFL 0.8

double sdf__sussman_dt(const sdf__field_grid *g)
{
    double s = 0;
    for (int a = 0; a < 3; a++)
        s += 1 / (g->h[a] * g->h[a]);
    return CFL / sqrt(s);
}

int sdf__sussman_steps(const sdf__field_grid *g, double band)
{
    double diagonal = 0;
    for (int a = 0; a < 3; a++)
        diagonal += (g->h[a] * (double)(g->n[a] - 1)) * (g->h[a] * (double)(g->n[a] - 1));
    double reach = fmin(band, sqrt(diagonal)) + 2 * g->hmax;
    return (int)ceil(reach / sdf__sussman_dt(g));
}

typedef struct step {
    const sdf__field_grid *g;
    const float *src;
    float *dst;
    const float *sign;
    const uint8_t *state;
    const size_t *rows; /* the rows holding nodes to update */
    double dt;
} step;

static inline double sq(double x)
{
    return x * x;
}

/* One axis's term of H: dm = D-, dp = D+ (differences over h). */
static inline double axis_term(double dm, double dp, int positive)
{
    if (positive) /* max((D-^+)^2, (D+^-)^2) */
        return sdf__hi2(sq(sdf__hi2(dm, 0)), sq(sdf__lo2(dp, 0)));
    return sdf__hi2(sq(sdf__lo2(dm, 0)), sq(sdf__hi2(dp, 0)));
}

static void step_rows(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const step *p = ctx;
    const sdf__field_grid *g = p->g;
    size_t n0 = g->n[0], sy = n0, sz = n0 * g->n[1];
    double ih[3] = {1 / g->h[0], 1 / g->h[1], 1 / g->h[2]};
    for (size_t x = begin; x < end; x++) {
        size_t r = p->rows[x], j = r % g->n[1], k = r / g->n[1], row = r * n0;
        for (size_t i = 0; i < n0; i++) {
            size_t at = row + i;
            double v = p->src[at];
            if ((p->state[at] & (SDF__NODE_FROZEN | SDF__NODE_ACTIVE)) != SDF__NODE_ACTIVE)
                continue; /* the same in both buffers */
            double xm = i > 0 ? p->src[at - 1] : v, xp = i + 1 < n0 ? p->src[at + 1] : v;
            double ym = j > 0 ? p->src[at - sy] : v, yp = j + 1 < g->n[1] ? p->src[at + sy] : v;
            double zm = k > 0 ? p->src[at - sz] : v, zp = k + 1 < g->n[2] ? p->src[at + sz] : v;
            double s = p->sign[at];
            int positive = s >= 0;
            double h2 = axis_term((v - xm) * ih[0], (xp - v) * ih[0], positive) +
                        axis_term((v - ym) * ih[1], (yp - v) * ih[1], positive) +
                        axis_term((v - zm) * ih[2], (zp - v) * ih[2], positive);
            p->dst[at] = (float)(v - p->dt * s * (sqrt(h2) - 1));
        }
    }
}

int sdf__sussman_solve(const sdf__field_grid *g, float *phi, const sdf__redist_scratch *s,
                       const sdf__redist_job *job, sdf__redist_result *res)
{
    int needed = sdf__sussman_steps(g, job->band);
    int steps = job->iterations > 0 ? job->iterations : needed;
    size_t rows = sdf__field_rows(g), count = 0;
    size_t *list = malloc(rows * sizeof *list);
    if (!list)
        return SDF_ENOMEM;
    for (size_t r = 0; r < rows; r++) {
        int any = 0;
        for (size_t at = r * g->n[0]; at < (r + 1) * g->n[0] && !any; at++)
            any = (s->state[at] & (SDF__NODE_FROZEN | SDF__NODE_ACTIVE)) == SDF__NODE_ACTIVE;
        if (any)
            list[count++] = r;
    }
    memcpy(s->work, phi, g->nodes * sizeof *phi); /* the nodes not updated, in both */
    step p = {.g = g, .sign = s->sign, .state = s->state, .rows = list,
              .dt = sdf__sussman_dt(g)};
    float *a = phi, *b = s->work;
    size_t chunk = sdf__field_row_chunk(g);
    int rc = 0;
    for (int n = 0; n < steps && !rc; n++) {
        p.src = a, p.dst = b;
        sdf__parallel_for(count, chunk, g->threads, step_rows, &p);
        float *t = a;
        a = b, b = t;
        if (job->tick && job->tick(job->tick_ctx, (double)(n + 1) / steps))
            rc = SDF_ECANCELED;
    }
    free(list);
    if (rc)
        return rc;
    if (a != phi)
        memcpy(phi, a, g->nodes * sizeof *phi);
    res->steps = steps;
    res->reached = fmax(0, steps * p.dt - 2 * g->hmax);
    return 0;
}
