/* redist.c - the set-up and finish shared by both re-distancing solvers.
 *
 * 1. Initial condition: the rounding paper's first-order normalization (its "Normalization
 *    and re-initialization" section, the phi(x, t = 0) below eq. (1)):
 *    phi0 = f / sqrt(f^2 + |grad f|^2). The formula mixes a value with a gradient, so it
 *    depends on the unit of length; it is applied with the grid's longest side as the unit
 *    (f / L against grad f), which is the paper's formula on a model scaled to a unit box and
 *    makes the result independent of the volume's units. phi0 has f's zero set and is
 *    close to the signed distance near it whatever f's scale.
 * 2. Interface: nodes with a neighbour of the other sign are held at the distance to the
 *    plane through phi0's linear crossings on their axes, 1 / sqrt(sum 1 / d_a^2). Eq. (1)
 *    alone lets the zero set drift (its upwind differences across the interface mix both
 *    sides; Russo & Smereka, J. Comput. Phys. 163, 2000); holding these nodes keeps the
 *    zero set where the samples put it, which their subcell fix converges to.
 * 3. Band: only nodes within ceil(band / hmin) + 2 nodes (Chebyshev) of the interface are
 *    solved; the others are at least (that count) hmin away and are clamped to it. */
#include "field/redist.h"

#include <math.h>

#include "core/parallel.h"
#include "field/exact.h"
#include "field/sussman.h"
#include "field/sweep.h"

typedef struct pass {
    const sdf__field_grid *g;
    const float *src;
    float *dst;
    float *sign;
    uint8_t *state;
    double unit;   /* normalization's length unit */
    double eps;    /* smoothed sign's epsilon */
    int axis;      /* band dilation: the axis of the lines */
    size_t reach;  /* band dilation: nodes */
    double cap;
    int signed_init; /* SUSSMAN starts from phi0, SWEEP from |distance| = cap */
} pass;

/* d/da of src at node (i, j, k) by central differences, one-sided on the grid's faces. */
static double diff(const pass *p, const float *v, size_t at, size_t ia, int a)
{
    const sdf__field_grid *g = p->g;
    size_t stride = a == 0 ? 1 : (a == 1 ? g->n[0] : g->n[0] * g->n[1]);
    size_t lo = ia > 0 ? at - stride : at, hi = ia + 1 < g->n[a] ? at + stride : at;
    return ((double)v[hi] - (double)v[lo]) / ((double)(hi - lo) / (double)stride * g->h[a]);
}

static void normalize_rows(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const pass *p = ctx;
    const sdf__field_grid *g = p->g;
    for (size_t r = begin; r < end; r++) {
        size_t j = r % g->n[1], k = r / g->n[1], row = r * g->n[0];
        for (size_t i = 0; i < g->n[0]; i++) {
            size_t at = row + i;
            double f = p->src[at], gx = diff(p, p->src, at, i, 0);
            double gy = diff(p, p->src, at, j, 1), gz = diff(p, p->src, at, k, 2);
            double den = sqrt(f / p->unit * (f / p->unit) + gx * gx + gy * gy + gz * gz);
            p->dst[at] = den > 0 ? (float)(f / den) : 0.0f;
        }
    }
}

/* The distance from node `at` to phi0's zero set estimated from its axis crossings, or
 * -1 when no neighbour has the other sign. */
static double crossing(const pass *p, size_t at, const size_t idx[3])
{
    const sdf__field_grid *g = p->g;
    const float *v = p->src;
    double f = v[at], inv2 = 0;
    int neg = f < 0, any = 0;
    size_t stride = 1;
    for (int a = 0; a < 3; a++) {
        double best = INFINITY;
        for (int side = -1; side <= 1; side += 2) {
            if ((side < 0 && idx[a] == 0) || (side > 0 && idx[a] + 1 == g->n[a]))
                continue;
            double nb = v[side < 0 ? at - stride : at + stride];
            if ((nb < 0) == neg)
                continue;
            double t = f / (f - nb); /* where the linear interpolant crosses zero */
            if (t * g->h[a] < best)
                best = t * g->h[a];
        }
        if (best < INFINITY) {
            any = 1;
            if (best <= 0)
                return 0;
            inv2 += 1 / (best * best);
        }
        stride *= g->n[a];
    }
    return any ? 1 / sqrt(inv2) : -1;
}

static void interface_rows(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const pass *p = ctx;
    const sdf__field_grid *g = p->g;
    for (size_t r = begin; r < end; r++) {
        size_t idx[3] = {0, r % g->n[1], r / g->n[1]}, row = r * g->n[0];
        for (size_t i = 0; i < g->n[0]; i++) {
            size_t at = row + i;
            idx[0] = i;
            double f = p->src[at], d = crossing(p, at, idx);
            uint8_t s = f < 0 ? SDF__NODE_NEG : 0;
            if (d >= 0) {
                s |= SDF__NODE_FROZEN | SDF__NODE_ACTIVE;
                p->dst[at] = (float)(f < 0 ? -d : d);
            } else {
                p->dst[at] = (float)f;
            }
            p->state[at] = s;
            if (p->sign) /* the paper's smoothed sign f / sqrt(f^2 + eps^2) */
                p->sign[at] = (float)(f / sqrt(f * f + p->eps * p->eps));
        }
    }
}

/* One pass of the band's separable dilation by a cube: along `axis`, mark every node within
 * `reach` nodes of a node marked by the previous pass. */
static void dilate_lines(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const pass *p = ctx;
    const sdf__field_grid *g = p->g;
    static const uint8_t from[3] = {SDF__NODE_FROZEN, SDF__NODE_STAGE1, SDF__NODE_STAGE2};
    static const uint8_t to[3] = {SDF__NODE_STAGE1, SDF__NODE_STAGE2, SDF__NODE_ACTIVE};
    int a = p->axis, b = (a + 1) % 3, c = (a + 2) % 3;
    size_t st[3] = {1, g->n[0], g->n[0] * g->n[1]};
    for (size_t line = begin; line < end; line++) {
        size_t base = (line % g->n[b]) * st[b] + (line / g->n[b]) * st[c];
        size_t len = g->n[a], last = SIZE_MAX; /* last marked index seen */
        for (size_t t = 0; t < len; t++) { /* forward: distance to the previous mark */
            uint8_t *s = &p->state[base + t * st[a]];
            if (*s & from[a])
                last = t;
            if (last != SIZE_MAX && t - last <= p->reach)
                *s |= to[a];
        }
        last = SIZE_MAX;
        for (size_t t = len; t-- > 0;) {
            uint8_t *s = &p->state[base + t * st[a]];
            if (*s & from[a])
                last = t;
            if (last != SIZE_MAX && last - t <= p->reach)
                *s |= to[a];
        }
    }
}

/* Non-interface nodes: the solvers' starting values, clamped to the band's cap. */
static void init_rows(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const pass *p = ctx;
    const sdf__field_grid *g = p->g;
    float cap = (float)p->cap;
    for (size_t at = begin * g->n[0]; at < end * g->n[0]; at++) {
        uint8_t s = p->state[at];
        if (s & SDF__NODE_FROZEN) {
            if (!p->signed_init)
                p->dst[at] = fabsf(p->dst[at]);
            continue;
        }
        float v = p->dst[at];
        if (p->signed_init && (s & SDF__NODE_ACTIVE))
            p->dst[at] = v < -cap ? -cap : (v > cap ? cap : v);
        else
            p->dst[at] = p->signed_init && (s & SDF__NODE_NEG) ? -cap : cap;
    }
}

/* The finish: SWEEP's unsigned distances get their sign; all are clamped to the cap. */
static void finish_rows(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const pass *p = ctx;
    const sdf__field_grid *g = p->g;
    float cap = (float)p->cap;
    for (size_t at = begin * g->n[0]; at < end * g->n[0]; at++) {
        float v = fabsf(p->dst[at]);
        v = v > cap ? cap : v;
        p->dst[at] = p->state[at] & SDF__NODE_NEG ? -v : v;
    }
}

static void run(const sdf__field_grid *g, size_t items, size_t chunk, sdf__range_fn fn, pass *p)
{
    sdf__parallel_for(items, chunk, g->threads, fn, p);
}

/* Marks the band (SDF__NODE_ACTIVE) and returns its cap. */
static double mark_band(const sdf__field_grid *g, pass *p, double band)
{
    size_t longest = g->n[0] > g->n[1] ? g->n[0] : g->n[1];
    longest = longest > g->n[2] ? longest : g->n[2];
    double diagonal = 0;
    for (int a = 0; a < 3; a++)
        diagonal += (g->h[a] * (double)(g->n[a] - 1)) * (g->h[a] * (double)(g->n[a] - 1));
    diagonal = sqrt(diagonal);
    double reach = isfinite(band) ? ceil(band / g->hmin) + 2 : (double)longest;
    if (reach >= (double)longest) {
        for (size_t at = 0; at < g->nodes; at++)
            p->state[at] |= SDF__NODE_ACTIVE;
        return 2 * diagonal; /* more than any distance within the grid */
    }
    p->reach = (size_t)reach;
    for (int a = 0; a < 3; a++) {
        p->axis = a;
        size_t lines = g->nodes / g->n[a];
        size_t chunk = 16384 / g->n[a] ? 16384 / g->n[a] : 1;
        run(g, lines, chunk, dilate_lines, p);
    }
    return reach * g->hmin;
}

int sdf__field_redistance(const sdf__field_grid *g, float *phi, const sdf__redist_scratch *s,
                          const sdf__redist_job *job, sdf__redist_result *res)
{
    double unit = 0;
    for (int a = 0; a < 3; a++)
        unit = fmax(unit, g->h[a] * (double)(g->n[a] - 1));
    pass p = {.g = g, .src = phi, .dst = s->work, .state = s->state, .unit = unit,
              .eps = g->hmin, .signed_init = job->solver == SDF_FIELD_SUSSMAN};
    sdf_mesh *surface = NULL; /* EXACT: from the field as given, before anything moves it */
    int rc = job->solver == SDF_FIELD_EXACT ? sdf__exact_surface(g, phi, &surface) : 0;
    if (rc)
        return rc;
    size_t rows = sdf__field_rows(g), chunk = sdf__field_row_chunk(g);
    run(g, rows, chunk, normalize_rows, &p);
    p.src = s->work, p.dst = phi, p.sign = p.signed_init ? s->sign : NULL;
    run(g, rows, chunk, interface_rows, &p);
    size_t frozen = 0;
    for (size_t at = 0; at < g->nodes && !frozen; at++)
        frozen = s->state[at] & SDF__NODE_FROZEN;
    if (!frozen) {
        sdf_mesh_release(surface);
        return SDF_EINVAL;
    }
    p.cap = mark_band(g, &p, job->band);
    res->cap = p.cap;
    if (surface) {
        rc = sdf__exact_solve(g, surface, s->state, (float)p.cap, phi);
        sdf_mesh_release(surface);
        res->steps = 0, res->reached = p.cap;
    } else {
        run(g, rows, chunk, init_rows, &p);
        rc = job->solver == SDF_FIELD_SUSSMAN ? sdf__sussman_solve(g, phi, s, job, res)
                                              : sdf__sweep_solve(g, phi, s->state, job, res);
    }
    if (rc)
        return rc;
    run(g, rows, chunk, finish_rows, &p);
    return 0;
}
