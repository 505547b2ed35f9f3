/* sweep.c - Godunov fast sweeping (Zhao 2005; see sweep.h). Each sweep visits the nodes in
 * one of the 8 orders (x, y, z each ascending or descending) and updates a node in place
 * from its current neighbours by the local solution of the upwind discretization: with
 * a_x, a_y, a_z the smaller neighbour along each axis (sorted ascending), the largest u
 * with sum over the a_i < u of ((u - a_i) / h_i)^2 = 1, kept if below the node's value.
 * Information moving in any direction is carried across the grid by the sweep whose order
 * follows it, so a few rounds converge; the interface nodes (redist.c) are never changed.
 *
 * The sweeps are Gauss-Seidel, each node depending on the one just before it in the sweep's
 * order, so they run on the calling thread; the set-up and finish around them (redist.c)
 * are parallel. Only rows holding active nodes are visited, and of those only the ones
 * "unlocked" by a change of more than the tolerance in themselves or a neighbouring row
 * since their last visit (Bak, McLaughlin, Renzi's locking sweeps, by rows): a node whose
 * neighbours have not changed cannot change, so most of a second round is skipped. */
#include "field/sweep.h"

#include <math.h>
#include <stdlib.h>

#define TOLERANCE 1e-4 /* of the smallest spacing: a converged round changes less */
#define MAX_ROUNDS 64  /* derived rounds stop here (each round at least doubles the reach) */

typedef struct sweeper {
    const sdf__field_grid *g;
    float *u;
    const uint8_t *state;
    const uint8_t *row_active; /* per row (j, k): holds an active, non-frozen node */
    uint8_t *unlocked;         /* per row: a neighbour changed since the row's last visit */
    double tol;
    double w[3];               /* 1 / h^2 */
    double h[3];
} sweeper;

/* The local solution at node `at` from its neighbours' minima a[3] (INFINITY: none). */
static double local_solve(const sweeper *s, double a0, double a1, double a2)
{
    double a[3] = {a0, a1, a2}, h[3] = {s->h[0], s->h[1], s->h[2]}, w[3] = {s->w[0], s->w[1], s->w[2]};
    for (int x = 0; x < 2; x++) /* sort the three by a, ascending */
        for (int y = 0; y < 2 - x; y++)
            if (a[y] > a[y + 1]) {
                double t = a[y]; a[y] = a[y + 1]; a[y + 1] = t;
                t = h[y]; h[y] = h[y + 1]; h[y + 1] = t;
                t = w[y]; w[y] = w[y + 1]; w[y + 1] = t;
            }
    double u = a[0] + h[0];
    if (!(u > a[1]))
        return u;
    /* sum_i w_i (u - a_i)^2 = 1 over the first m: A u^2 - 2 B u + C = 0 */
    double A = w[0] + w[1], B = w[0] * a[0] + w[1] * a[1];
    double C = w[0] * a[0] * a[0] + w[1] * a[1] * a[1] - 1;
    u = (B + sqrt(sdf__hi2(B * B - A * C, 0))) / A;
    if (!(u > a[2]))
        return u;
    A += w[2], B += w[2] * a[2], C += w[2] * a[2] * a[2];
    return (B + sqrt(sdf__hi2(B * B - A * C, 0))) / A;
}

/* One sweep in the order given by dir[3] (+1 ascending, -1 descending); the largest change. */
static double sweep(const sweeper *s, const int dir[3])
{
    const sdf__field_grid *g = s->g;
    size_t n0 = g->n[0], n1 = g->n[1], n2 = g->n[2], sy = n0, sz = n0 * n1;
    float *u = s->u;
    double change = 0;
    for (size_t kk = 0; kk < n2; kk++) {
        size_t k = dir[2] > 0 ? kk : n2 - 1 - kk;
        for (size_t jj = 0; jj < n1; jj++) {
            size_t j = dir[1] > 0 ? jj : n1 - 1 - jj;
            size_t r = k * n1 + j;
            if (!s->unlocked[r])
                continue;
            s->unlocked[r] = 0;
            size_t row = r * n0;
            double row_change = 0;
            for (size_t ii = 0; ii < n0; ii++) {
                size_t i = dir[0] > 0 ? ii : n0 - 1 - ii, at = row + i;
                if ((s->state[at] & (SDF__NODE_FROZEN | SDF__NODE_ACTIVE)) != SDF__NODE_ACTIVE)
                    continue;
                double ax = sdf__lo2(i > 0 ? u[at - 1] : INFINITY, i + 1 < n0 ? u[at + 1] : INFINITY);
                double ay = sdf__lo2(j > 0 ? u[at - sy] : INFINITY, j + 1 < n1 ? u[at + sy] : INFINITY);
                double az = sdf__lo2(k > 0 ? u[at - sz] : INFINITY, k + 1 < n2 ? u[at + sz] : INFINITY);
                double v = local_solve(s, ax, ay, az);
                if (v < u[at]) {
                    row_change = sdf__hi2(row_change, u[at] - v);
                    u[at] = (float)v;
                }
            }
            change = sdf__hi2(change, row_change);
            if (row_change > s->tol) { /* the row and its four neighbour rows may change */
                s->unlocked[r] = 1;
                if (j > 0)
                    s->unlocked[r - 1] = s->row_active[r - 1];
                if (j + 1 < n1)
                    s->unlocked[r + 1] = s->row_active[r + 1];
                if (k > 0)
                    s->unlocked[r - n1] = s->row_active[r - n1];
                if (k + 1 < n2)
                    s->unlocked[r + n1] = s->row_active[r + n1];
            }
        }
    }
    return change;
}

int sdf__sweep_solve(const sdf__field_grid *g, float *phi, const uint8_t *state,
                     const sdf__redist_job *job, sdf__redist_result *res)
{
    size_t rows = sdf__field_rows(g);
    uint8_t *row_active = malloc(rows), *unlocked = malloc(rows);
    if (!row_active || !unlocked) {
        free(row_active);
        free(unlocked);
        return SDF_ENOMEM;
    }
    for (size_t r = 0; r < rows; r++) {
        uint8_t any = 0;
        for (size_t at = r * g->n[0]; at < (r + 1) * g->n[0] && !any; at++)
            any = (state[at] & (SDF__NODE_FROZEN | SDF__NODE_ACTIVE)) == SDF__NODE_ACTIVE;
        row_active[r] = unlocked[r] = any;
    }
    double tol = TOLERANCE * g->hmin;
    sweeper s = {.g = g, .u = phi, .state = state, .row_active = row_active,
                 .unlocked = unlocked, .tol = tol};
    for (int a = 0; a < 3; a++)
        s.h[a] = g->h[a], s.w[a] = 1 / (g->h[a] * g->h[a]);
    int rounds = job->iterations > 0 ? job->iterations : MAX_ROUNDS, done = 0;
    double change = INFINITY;
    int rc = 0;
    for (; done < rounds && !(job->iterations == 0 && change <= tol); done++) {
        change = 0;
        for (int o = 0; o < 8 && !rc; o++) {
            int dir[3] = {o & 1 ? -1 : 1, o & 2 ? -1 : 1, o & 4 ? -1 : 1};
            change = fmax(change, sweep(&s, dir));
            /* Rounds to come are unknown: report a round as a third of the work. */
            if (job->tick && job->tick(job->tick_ctx, fmin(1, (done + (o + 1) / 8.0) / 3)))
                rc = SDF_ECANCELED;
        }
        if (rc)
            break;
    }
    free(row_active);
    free(unlocked);
    res->steps = done;
    res->reached = change <= tol ? job->band : 0;
    return rc;
}
