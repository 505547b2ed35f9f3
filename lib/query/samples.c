/* samples.c - the filtered field's parameters and sample sets (see samples.h): the zero
 * defaults of sdf_filter_options resolved for a mesh and every value checked, then the
 * displacements and weights a request's samples use, drawn from its seed. Apart from the
 * evaluation (filter.c) because bakes resolve options too and tests look at the samples. */
#include "query/samples.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/diag.h"

#define DEFAULT_CAP_OF_DIAGONAL 0.02
#define DEFAULT_MEDIAL 0.2

/* ---- sample sets ------------------------------------------------------------------------ */

/* splitmix64: a tiny, well-mixed generator, so a seed means the same samples everywhere. */
static uint64_t next_random(uint64_t *state)
{
    uint64_t z = (*state += 0x9e3779b97f4a7c15u);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
    return z ^ (z >> 31);
}

/* Uniform in (0, 1]: never 0, so log() below is finite. */
static double uniform01(uint64_t *state)
{
    return ((double)(next_random(state) >> 11) + 1.0) / 9007199254740992.0;
}

/* The bump's shape without its constant: exp(1 / (t^2 - 1)) for t = |u| / b < 1. */
static double bump_shape(double t2)
{
    return t2 < 1 ? exp(1 / (t2 - 1)) : 0;
}

static int draw_random(const sdf_filter_options *f, sdf__samples *s)
{
    uint64_t state = f->seed;
    double sigma = sdf__gaussian_sigma(f->a);
    for (int i = 0; i < s->n; i++) {
        double *o = s->offset[i];
        if (f->kernel == SDF_KERNEL_GAUSSIAN) {
            /* Box-Muller: two uniforms give two independent standard normals. */
            double z[4];
            for (int k = 0; k < 4; k += 2) {
                double radius = sqrt(-2 * log(uniform01(&state)));
                double angle = 2 * M_PI * uniform01(&state);
                z[k] = radius * cos(angle);
                z[k + 1] = radius * sin(angle);
            }
            for (int k = 0; k < 3; k++)
                o[k] = sigma * z[k];
        } else {
            /* Rejection from the uniform cube [-1, 1]^3: accept with w(u) / max w, where
             * max w = w(0) = e^-1 (then scale by b, eq. 6). Acceptance is ~15 %. */
            for (;;) {
                double u[3], t2 = 0;
                for (int k = 0; k < 3; k++) {
                    u[k] = 2 * uniform01(&state) - 1;
                    t2 += u[k] * u[k];
                }
                if (uniform01(&state) <= bump_shape(t2) * M_E) {
                    for (int k = 0; k < 3; k++)
                        o[k] = f->b * u[k];
                    break;
                }
            }
        }
        s->weight[i] = 1.0 / s->n;
    }
    return 0;
}

/* Eq. (9): the 3^3 grid at 0 and +-spacing on each axis, weighted by the kernel there. */
static void draw_grid(const sdf_filter_options *f, sdf__samples *s)
{
    double spacing = f->kernel == SDF_KERNEL_GAUSSIAN ? sdf__gaussian_sigma(f->a) : f->b / 2;
    double total = 0;
    int i = 0;
    for (int x = -1; x <= 1; x++)
        for (int y = -1; y <= 1; y++)
            for (int z = -1; z <= 1; z++, i++) {
                double k2 = x * x + y * y + z * z;
                s->offset[i][0] = x * spacing, s->offset[i][1] = y * spacing;
                s->offset[i][2] = z * spacing;
                /* Gaussian at distance sqrt(k2) sigma: exp(-k2/2); bump at t = sqrt(k2)/2. */
                s->weight[i] = f->kernel == SDF_KERNEL_GAUSSIAN ? exp(-k2 / 2) : bump_shape(k2 / 4);
                total += s->weight[i];
            }
    for (i = 0; i < 27; i++)
        s->weight[i] /= total;
}

int sdf__samples_draw(const sdf_filter_options *f, sdf__samples *out)
{
    int n = f->grid ? 27 : f->samples;
    out->n = n;
    out->offset = malloc((size_t)n * sizeof *out->offset);
    out->weight = malloc((size_t)n * sizeof *out->weight);
    if (!out->offset || !out->weight) {
        sdf__samples_free(out);
        return SDF_ENOMEM;
    }
    if (f->grid)
        draw_grid(f, out);
    else
        draw_random(f, out);
    return 0;
}

void sdf__samples_free(sdf__samples *s)
{
    free(s->offset);
    free(s->weight);
    memset(s, 0, sizeof *s);
}

/* ---- parameters ------------------------------------------------------------------------- */

static int positive(double v) { return isfinite(v) && v > 0; }

/* The kernel, its cap and widths of `out` (sdf_filter_options), defaults filled in for a
 * mesh of this diagonal. 0 or SDF_EINVAL with its message. */
static int resolve_kernel(sdf_filter_options *out, double diagonal, sdf_diag *diag)
{
    if (out->kernel != SDF_KERNEL_GAUSSIAN && out->kernel != SDF_KERNEL_BUMP)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown kernel %d", (int)out->kernel);
    if (out->cap == 0)
        out->cap = DEFAULT_CAP_OF_DIAGONAL * (diagonal > 0 ? diagonal : 1);
    if (!positive(out->cap))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "cap (f_c) must be a positive number");
    /* The kernel widths default to the cap's scale; a cap so small or large that they would
     * overflow or vanish is the cap's fault, and the message says so. */
    if (out->a == 0) {
        out->a = 8 / (out->cap * out->cap);
        if (!positive(out->a))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "cap (f_c) = %g is out of range: the Gaussian's default a = 8 / "
                                 "f_c^2 is %g; choose another cap or give a",
                                 out->cap, out->a);
    }
    if (out->b == 0) {
        out->b = 8 * out->cap / 9;
        if (!positive(out->b))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "cap (f_c) = %g is out of range: the bump's default width b = "
                                 "8 f_c / 9 is %g; choose another cap or give b",
                                 out->cap, out->b);
    }
    if (!positive(out->a))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "the Gaussian's a must be a positive number");
    if (!positive(out->b))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                             "the bump's width b must be a positive number");
    return 0;
}

/* The smoothing volume of `out`, checked, with its depth and scale defaults. */
static int resolve_volume(sdf_filter_options *out, sdf_diag *diag)
{
    sdf_smoothing_volume *v = &out->smooth;
    switch (v->shape) {
    case SDF_VOLUME_NONE:
        break;
    case SDF_VOLUME_SPHERE:
        if (!isfinite(v->center[0]) || !isfinite(v->center[1]) || !isfinite(v->center[2]) ||
            !positive(v->radius))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "a smoothing sphere needs a finite centre and a radius > 0");
        break;
    case SDF_VOLUME_BOX:
        for (int k = 0; k < 3; k++)
            if (!isfinite(v->lo[k]) || !isfinite(v->hi[k]) || !(v->lo[k] < v->hi[k]))
                return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                     "a smoothing box needs finite corners with lo < hi on "
                                     "every axis");
        break;
    case SDF_VOLUME_MESH:
        if (!v->mesh)
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "a smoothing mesh is missing");
        break;
    default:
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown smoothing volume %d", (int)v->shape);
    }
    if (v->shape != SDF_VOLUME_NONE) {
        if (v->depth == 0)
            v->depth = out->cap;
        if (v->scale == 0)
            v->scale = 1;
        if (!positive(v->depth) || !positive(v->scale))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "smoothing depth and scale must be positive numbers");
    }
    return 0;
}

/* The sample count of `out`, checked, with its default. */
static int resolve_samples(sdf_filter_options *out, sdf_diag *diag)
{
    if (out->samples == 0)
        out->samples = SDF_FILTER_DEFAULT_SAMPLES;
    if (out->samples < 1 || out->samples > SDF_FILTER_MAX_SAMPLES)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "samples must be 1..%d, not %d",
                             SDF_FILTER_MAX_SAMPLES, out->samples);
    return 0;
}

/* Adaptive quality (min_samples) of `out`, checked, with its medial default. */
static int resolve_adaptive(sdf_filter_options *out, sdf_diag *diag)
{
    if (out->min_samples != 0) {
        if (out->min_samples < 1 || out->min_samples > out->samples)
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "min_samples must be 1..samples (%d), not %d", out->samples,
                                 out->min_samples);
        if (out->grid)
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "adaptive quality draws random samples; it cannot use the grid");
        if (out->medial == 0)
            out->medial = DEFAULT_MEDIAL;
        if (!positive(out->medial))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "medial must be a positive number");
    }
    return 0;
}

int sdf__filter_resolve(const sdf_mesh *mesh, const sdf_filter_options *in,
                        sdf_filter_options *out, sdf_diag *diag)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    *out = in ? *in : (sdf_filter_options){0};
    int rc = resolve_kernel(out, r.diagonal, diag);
    if (!rc)
        rc = resolve_samples(out, diag);
    if (!rc)
        rc = resolve_volume(out, diag);
    if (!rc)
        rc = resolve_adaptive(out, diag);
    if (rc)
        return rc;
    const sdf_smoothing_volume *v = &out->smooth;
    /* Eq. (7): the kernel must not reach across the surface, b h(p) <= |f(p)| for all p. It
     * bounds eq. (4)'s kernel size; localized smoothing edits the surface on purpose. */
    if (v->shape == SDF_VOLUME_NONE && out->kernel == SDF_KERNEL_BUMP && !out->allow_wide_bump &&
        out->b > 8 * out->cap / 9 * (1 + 1e-12))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                             "bump width b = %g exceeds 8 f_c / 9 = %g (f_c = %g), which may "
                             "create extra zero level sets; lower b, raise the cap, or allow "
                             "a wide bump explicitly",
                             out->b, 8 * out->cap / 9, out->cap);
    return 0;
}
