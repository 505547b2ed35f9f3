/* ops.c - sdf_volume_apply_ops (sdf.h, "Field operations"): checks the volume, the ops and
 * the options, plans the steps (plan.h), runs them on a copy of the node values, and checks
 * the rounding paper's validity caveats on the way:
 *  - band: a re-distancing whose iterations were overridden below what its band needs;
 *  - grid: a dilation whose surface, with the band it must be exact in, reaches the grid's
 *    boundary where the field was outside: the grid holds nothing beyond to offset;
 *  - topology: "restrict the offset radius such that no boundary points after the offset
 *    are on the medial axis" (its Offsetting section) - an offset past the medial axis
 *    splits, removes or fuses parts, so the number of parts of the solid and of its outside
 *    is compared after every offset's re-distancing (topology.h). This misses a thin fin
 *    that vanishes without changing any count.
 * An erosion that removes the whole solid, or a dilation that fills the grid, is an error. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/bigmem.h"
#include "core/diag.h"
#include "field/plan.h"
#include "field/redist.h"
#include "field/sussman.h"
#include "field/topology.h"
#include "volume/volume.h"

#define DEFAULT_BAND_CELLS 4 /* the result's exact band by default, in smallest spacings */
#define MARGIN_CELLS 2       /* what a re-distancing needs of its input, in largest spacings */

#define NAME_ENTRY(name, value, str) [value] = str,
static const char *const op_names[] = {SDF_FIELD_OP_MAP(NAME_ENTRY)};
static const char *const solver_names[] = {SDF_FIELD_SOLVER_MAP(NAME_ENTRY)};
#undef NAME_ENTRY
#define COUNT(a) (sizeof(a) / sizeof((a)[0]))

static int name_index(const char *name, const char *const *names, size_t count)
{
    for (size_t i = 0; name && i < count; i++)
        if (names[i] && !strcasecmp(name, names[i]))
            return (int)i;
    return -1;
}

int sdf_field_op_from_name(const char *name, sdf_field_op_kind *out)
{
    int i = name_index(name, op_names, COUNT(op_names));
    if (i < 0)
        return SDF_EINVAL;
    *out = (sdf_field_op_kind)i;
    return 0;
}

const char *sdf_field_op_name(sdf_field_op_kind kind)
{
    return (unsigned)kind < COUNT(op_names) ? op_names[kind] : "unknown";
}

int sdf_field_solver_from_name(const char *name, sdf_field_solver *out)
{
    int i = name_index(name, solver_names, COUNT(solver_names));
    if (i < 0)
        return SDF_EINVAL;
    *out = (sdf_field_solver)i;
    return 0;
}

const char *sdf_field_solver_name(sdf_field_solver solver)
{
    return (unsigned)solver < COUNT(solver_names) ? solver_names[solver] : "unknown";
}

typedef struct run {
    sdf__field_grid g;
    const sdf_field_op *ops;
    const sdf_field_options *opts;
    float *phi;
    sdf__redist_scratch s;
    uint32_t *labels;
    size_t redistancings, done; /* for progress */
    unsigned caveats;
    sdf_diag *diag;
    char first[256];            /* the first caveat's message */
} run;

static int check_opts(const sdf_field_options *o, sdf_diag *diag)
{
    if ((unsigned)o->solver >= COUNT(solver_names))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown re-distancing solver %d",
                             (int)o->solver);
    if (o->iterations < 0 || o->threads < 0)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "iterations and threads must be >= 0");
    if (!(isfinite(o->band) && o->band >= 0))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "band must be a finite length >= 0");
    return 0;
}

static int check_volume(const sdf_volume *in, double *diagonal, sdf_diag *diag)
{
    const sdf_volume_info *info = &in->info;
    if (info->order != 0 || info->encoding != SDF_ENCODING_FLOAT32)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                             "field operations take zero-order float32 volumes; this one is "
                             "order %d %s (bake it with order 0)", info->order,
                             sdf_encoding_name(info->encoding));
    *diagonal = 0;
    for (int a = 0; a < 3; a++) {
        if (info->dims[a] < 2)
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "volume dimension %c is %zu; field operations need >= 2",
                                 "xyz"[a], info->dims[a]);
        double side = info->spacing[a] * (double)(info->dims[a] - 1);
        *diagonal += side * side;
    }
    *diagonal = sqrt(*diagonal);
    for (size_t at = 0; at < in->nodes; at++)
        if (!isfinite(in->data.f[at]))
            return sdf__diag_set(diag, SDF_ENONFINITE, 0, -1,
                                 "node %zu of the volume holds %g; field operations need "
                                 "finite values", at, (double)in->data.f[at]);
    return 0;
}

static int check_ops(const sdf_field_op *ops, size_t count, double diagonal, sdf_diag *diag)
{
    if (!ops || count == 0 || count > SDF_FIELD_MAX_OPS)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "give 1..%d field operations, not %zu",
                             SDF_FIELD_MAX_OPS, ops ? count : 0);
    for (size_t o = 0; o < count; o++) {
        double r = ops[o].r;
        if ((unsigned)ops[o].kind >= COUNT(op_names))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "operation %zu: unknown kind %d", o,
                                 (int)ops[o].kind);
        const char *name = op_names[ops[o].kind];
        if (!isfinite(r))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "operation %zu (%s): r is not finite",
                                 o, name);
        if (ops[o].kind == SDF_FIELD_REDISTANCE ? r < 0
                                                : ops[o].kind != SDF_FIELD_OFFSET && !(r > 0))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "operation %zu (%s): r must be %s, "
                                 "not %g", o, name, ops[o].kind == SDF_FIELD_REDISTANCE
                                 ? ">= 0 (0: the whole grid)" : "> 0", r);
        if (fabs(r) >= diagonal)
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "operation %zu (%s): |r| = %g reaches "
                                 "past the grid (its diagonal is %g)", o, name, fabs(r),
                                 diagonal);
    }
    return 0;
}

/* Record a caveat: its bit, and the message if it is the first. */
static void caveat(run *w, unsigned bit, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void caveat(run *w, unsigned bit, const char *fmt, ...)
{
    if (!w->caveats) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(w->first, sizeof w->first, fmt, ap);
        va_end(ap);
    }
    w->caveats |= bit;
}

static int tick(void *ctx, double fraction)
{
    run *w = ctx;
    const sdf_field_options *o = w->opts;
    return o->progress && o->progress(o->user, (w->done + fraction) / (double)w->redistancings);
}

static int redistance_step(run *w, const sdf__field_step *st, double diagonal)
{
    const sdf_field_op *op = &w->ops[st->op];
    sdf__redist_job job = {.solver = w->opts->solver, .band = st->band,
                           .iterations = w->opts->iterations, .tick = tick, .tick_ctx = w};
    sdf__redist_result res;
    int rc = sdf__field_redistance(&w->g, w->phi, &w->s, &job, &res);
    if (rc == SDF_EINVAL)
        return sdf__diag_set(w->diag, rc, 0, -1, "operation %zu (%s): the field has no zero "
                             "crossing in the grid: there is no surface to re-distance",
                             st->op, sdf_field_op_name(op->kind));
    if (rc == SDF_ECANCELED)
        return sdf__diag_set(w->diag, rc, 0, -1, "the field operations were canceled");
    if (rc)
        return sdf__diag_set(w->diag, rc, 0, -1, "out of memory re-distancing");
    w->done++;
    if (tick(w, 0)) /* the solver's last report may fall short of its end (SWEEP) */
        return sdf__diag_set(w->diag, SDF_ECANCELED, 0, -1, "the field operations were canceled");
    double needed = fmin(st->band, diagonal);
    if (res.reached < needed * (1 - 1e-9)) {
        if (w->opts->solver == SDF_FIELD_SUSSMAN)
            caveat(w, SDF_FIELD_CAVEAT_BAND, "operation %zu (%s): %d re-distancing steps reach "
                   "%g from the surface, but it must be exact up to %g (iterations 0 derives "
                   "enough)", st->op, sdf_field_op_name(op->kind), res.steps, res.reached,
                   needed);
        else
            caveat(w, SDF_FIELD_CAVEAT_BAND, "operation %zu (%s): %d sweep rounds did not "
                   "converge (iterations 0 sweeps until they do)", st->op,
                   sdf_field_op_name(op->kind), res.steps);
    }
    return 0;
}

/* Whether a boundary node outside the solid comes within `band` of the surface after
 * phi += c: the grid cuts the dilated surface or the band it must be exact in. */
static int dilation_reaches_boundary(const run *w, double c, double band)
{
    const sdf__field_grid *g = &w->g;
    for (size_t r = 0; r < sdf__field_rows(g); r++) {
        size_t j = r % g->n[1], k = r / g->n[1], row = r * g->n[0];
        int face = j == 0 || k == 0 || j + 1 == g->n[1] || k + 1 == g->n[2];
        size_t step = face ? 1 : g->n[0] - 1;
        for (size_t i = 0; i < g->n[0]; i += step) {
            double v = w->phi[row + i];
            if (v > 0 && v + c < band)
                return 1;
        }
    }
    return 0;
}

static int shift_step(run *w, const sdf__field_step *st)
{
    const sdf_field_op *op = &w->ops[st->op];
    const char *name = sdf_field_op_name(op->kind);
    double c = st->shift;
    if (c < 0 && dilation_reaches_boundary(w, c, st->band))
        caveat(w, SDF_FIELD_CAVEAT_GRID, "operation %zu (%s, r = %g): the dilation by %g "
               "brings the surface within %g (the band it must be exact in) of the grid's "
               "boundary, which cuts it off there", st->op, name, (double)op->r, -c, st->band);
    size_t inside = 0;
    for (size_t at = 0; at < w->g.nodes; at++) {
        w->phi[at] = (float)(w->phi[at] + c);
        inside += w->phi[at] < 0;
    }
    if (inside == 0 || inside == w->g.nodes)
        return sdf__diag_set(w->diag, SDF_EINVAL, 0, -1, "operation %zu (%s, r = %g): the %s "
                             "by %g leaves no surface in the grid (%s)", st->op, name,
                             (double)op->r, c > 0 ? "erosion" : "dilation", fabs(c),
                             inside ? "the solid fills it" : "it removes the whole solid");
    return 0;
}

/* The topology caveat: compare the parts now with those after the previous check. */
static void check_parts(run *w, const sdf__field_step *st, sdf__field_parts *prev, int *have)
{
    sdf__field_parts now;
    sdf__field_count_parts(&w->g, w->phi, w->labels, &now);
    if (*have && (now.inside != prev->inside || now.outside != prev->outside)) {
        const sdf_field_op *op = &w->ops[st->op];
        caveat(w, SDF_FIELD_CAVEAT_TOPOLOGY, "operation %zu (%s, r = %g): an offset changed "
               "the solid's parts from %zu to %zu and its outside's from %zu to %zu: it "
               "crosses the medial axis (a part thinner than 2r vanished or split, or a gap "
               "narrower than 2r closed)", st->op, sdf_field_op_name(op->kind), (double)op->r,
               prev->inside, now.inside, prev->outside, now.outside);
    }
    *prev = now;
    *have = 1;
}

static int run_steps(run *w, const sdf__field_step *steps, size_t n, double diagonal)
{
    sdf__field_parts parts = {0, 0};
    int have = 0;
    for (size_t i = 0; i < n; i++) {
        int rc = steps[i].redistance ? redistance_step(w, &steps[i], diagonal)
                                     : shift_step(w, &steps[i]);
        if (rc)
            return rc;
        if (w->labels && (steps[i].redistance || i + 1 == n))
            check_parts(w, &steps[i], &parts, &have);
    }
    return 0;
}

static void release(run *w)
{
    sdf__big_free(w->phi);
    sdf__big_free(w->s.work);
    sdf__big_free(w->s.sign);
    sdf__big_free(w->s.state);
    sdf__big_free(w->labels);
}

static int setup(run *w, const sdf_volume *in, const sdf__field_step *steps, size_t n)
{
    int shifts = 0;
    for (size_t i = 0; i < n; i++) {
        w->redistancings += steps[i].redistance;
        shifts |= !steps[i].redistance;
    }
    size_t nodes = w->g.nodes; /* <= SDF_VOLUME_MAX_NODES: no product below overflows */
    w->phi = sdf__big_alloc(nodes * sizeof(float));
    w->s.work = sdf__big_alloc(nodes * sizeof(float));
    w->s.state = sdf__big_alloc(nodes);
    if (w->opts->solver == SDF_FIELD_SUSSMAN)
        w->s.sign = sdf__big_alloc(nodes * sizeof(float));
    if (shifts)
        w->labels = sdf__big_alloc(nodes * sizeof(uint32_t));
    if (!w->phi || !w->s.work || !w->s.state || (shifts && !w->labels) ||
        (w->opts->solver == SDF_FIELD_SUSSMAN && !w->s.sign))
        return sdf__diag_set(w->diag, SDF_ENOMEM, 0, -1, "out of memory for a %zu-node field "
                             "operation", nodes);
    memcpy(w->phi, in->data.f, nodes * sizeof(float));
    return 0;
}

int sdf_volume_apply_ops(const sdf_volume *in, const sdf_field_op *ops, size_t count,
                         const sdf_field_options *opts, sdf_volume **out, unsigned *caveats,
                         sdf_diag *diag)
{
    sdf__diag_clear(diag);
    if (caveats)
        *caveats = 0;
    if (!in || !out)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "no input volume or output pointer");
    *out = NULL;
    static const sdf_field_options defaults;
    opts = opts ? opts : &defaults;
    double diagonal = 0;
    int rc = check_opts(opts, diag);
    if (!rc)
        rc = check_volume(in, &diagonal, diag);
    if (!rc)
        rc = check_ops(ops, count, diagonal, diag);
    if (rc)
        return rc;
    run w = {.ops = ops, .opts = opts, .diag = diag};
    w.g.nodes = in->nodes, w.g.threads = opts->threads;
    w.g.hmin = INFINITY, w.g.hmax = 0;
    for (int a = 0; a < 3; a++) {
        w.g.n[a] = in->info.dims[a], w.g.h[a] = in->info.spacing[a];
        w.g.hmin = fmin(w.g.hmin, w.g.h[a]), w.g.hmax = fmax(w.g.hmax, w.g.h[a]);
    }
    sdf__field_step steps[SDF__FIELD_MAX_STEPS];
    double band = opts->band > 0 ? opts->band : DEFAULT_BAND_CELLS * w.g.hmin;
    size_t n = sdf__field_plan(ops, count, band, MARGIN_CELLS * w.g.hmax, steps);
    rc = setup(&w, in, steps, n);
    if (!rc)
        rc = run_steps(&w, steps, n, diagonal);
    if (!rc && w.caveats && opts->strict)
        rc = sdf__diag_set(diag, SDF_EINVAL, 0, -1, "%s", w.first);
    sdf_volume *v = NULL;
    if (!rc && (rc = sdf__volume_alloc(&in->info, &v)) != 0)
        sdf__diag_set(diag, rc, 0, -1, "out of memory for the result volume");
    if (!rc) {
        memcpy(v->data.f, w.phi, in->nodes * sizeof(float));
        *out = v;
        if (caveats)
            *caveats = w.caveats;
        if (w.caveats)
            sdf__diag_set(diag, 0, 0, -1, "%s", w.first);
    }
    release(&w);
    return rc;
}
