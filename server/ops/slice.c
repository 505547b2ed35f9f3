/* slice.c - a slice's URL arguments and its lattice of pixel centres (see slice.h). */
#include "ops/slice.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static const char *const mode_names[] = {"signed", "distance", "filtered", "gradient", "error"};

typedef struct parse {
    const sdfd_url_args *args;
    char *err;
    size_t cap;
    const char **argument;
} parse;

__attribute__((format(printf, 3, 4))) static int refuse(parse *p, const char *name,
                                                         const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(p->err, p->cap, fmt, ap);
    va_end(ap);
    *p->argument = name;
    return SDF_EINVAL;
}

static const char *value_of(const parse *p, const char *name)
{
    return sdfd_url_value(p->args, name);
}

/* "x,y,..." -> exactly n finite numbers within the library's coordinate range. */
static int numbers(const char *v, double *x, int n)
{
    for (int i = 0; i < n; i++) {
        char *end;
        errno = 0;
        x[i] = strtod(v, &end);
        if (end == v || errno || !isfinite(x[i]) || fabs(x[i]) > SDF_MAX_COORDINATE ||
            *end != (i + 1 < n ? ',' : '\0'))
            return -1;
        v = end + 1;
    }
    return 0;
}

static int parse_plane(parse *p, sdfd_slice_params *out)
{
    const char *axis = value_of(p, "axis"), *at = value_of(p, "at"),
               *normal = value_of(p, "normal"), *origin = value_of(p, "origin");
    out->axis = 2;
    if (axis) {
        if (strlen(axis) != 1 || !strchr("xyz", tolower((unsigned char)axis[0])))
            return refuse(p, "axis", "axis must be x, y or z, not '%.40s'", axis);
        out->axis = tolower((unsigned char)axis[0]) - 'x';
    }
    if (normal && axis)
        return refuse(p, "normal", "give axis (with at) or normal (with origin), not both");
    if (normal && at)
        return refuse(p, "at", "at goes with axis; a plane given by its normal takes origin");
    if (origin && !normal)
        return refuse(p, "origin", "origin goes with normal (axis takes at)");
    if (at && numbers(at, &out->at, 1))
        return refuse(p, "at", "at must be a finite number, not '%.40s'", at);
    out->has_at = at != NULL;
    if (normal) {
        double *n = out->normal, len;
        if (numbers(normal, n, 3) || !((len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])) > 0))
            return refuse(p, "normal", "normal must be nx,ny,nz, finite and not all zero");
        for (int a = 0; a < 3; a++)
            n[a] /= len;
        out->axis = -1;
    }
    if (origin && numbers(origin, out->origin, 3))
        return refuse(p, "origin", "origin must be x,y,z, three finite numbers");
    out->has_origin = origin != NULL;
    return 0;
}

static int parse_mode(parse *p, sdfd_slice_params *out)
{
    const char *mode = value_of(p, "mode"), *sign = value_of(p, "sign"),
               *interp = value_of(p, "interpolation");
    out->mode = SDFD_SLICE_SIGNED;
    if (mode) {
        size_t m = 0;
        while (m < 5 && strcasecmp(mode, mode_names[m]))
            m++;
        if (m == 5)
            return refuse(p, "mode", "unknown mode '%.40s' (signed, distance, filtered, gradient, "
                          "and error for volumes)", mode);
        out->mode = (sdfd_slice_mode)m;
    }
    if (out->volume && out->mode == SDFD_SLICE_FILTERED)
        return refuse(p, "mode", "mode filtered is a mesh's (a volume is sliced as baked)");
    if (!out->volume && out->mode == SDFD_SLICE_ERROR)
        return refuse(p, "mode", "mode error is a volume's: |volume - exact| on its mesh");
    out->sign = SDF_SIGN_AUTO; /* sign is a mesh slice's, interpolation a volume's (urlargs.c) */
    if (sign && sdf_sign_from_name(sign, &out->sign))
        return refuse(p, "sign", "unknown sign '%.40s' (auto, pseudonormal, winding, raycast, "
                      "none)", sign);
    out->interpolation = SDF_VOLUME_DEFAULT; /* as volume queries: hermite on first order */
    if (interp && sdf_volume_filter_from_name(interp, &out->interpolation))
        return refuse(p, "interpolation", "unknown interpolation '%.40s' (default, trilinear, "
                      "nearest, hermite)", interp);
    return 0;
}

static const char *one_arg(void *ctx, const char *name)
{
    const sdfd_url_arg *a = ctx;
    return !strcmp(a->name, name) ? a->value : NULL;
}

/* The filter's arguments through filterparams.c: each alone first, so that a refusal names
 * its argument (the smooth_* ones, which need each other, are named by the first given),
 * then all together. */
static int parse_filter(parse *p, sdfd_slice_params *out)
{
    const char *smooth = NULL;
    for (size_t i = 0; i < p->args->n; i++) {
        const sdfd_url_arg *a = &p->args->arg[i];
        if (!sdfd_filter_is_url_name(a->name))
            continue;
        if (out->mode != SDFD_SLICE_FILTERED)
            return refuse(p, a->name, "argument '%.40s' is the filter's: it goes with "
                          "mode=filtered", a->name);
        if (!strncmp(a->name, "smooth_", 7)) {
            smooth = smooth ? smooth : a->name;
            continue;
        }
        char err[256];
        if (sdfd_filter_from_strings(one_arg, (void *)a, &out->filter, out->smoothing_mesh, err,
                                     sizeof err))
            return refuse(p, a->name, "%s", err);
    }
    char err[256];
    if (sdfd_filter_from_strings(sdfd_url_lookup, (void *)p->args, &out->filter,
                                 out->smoothing_mesh, err, sizeof err))
        return refuse(p, smooth ? smooth : "", "%s", err);
    return 0;
}

int sdfd_slice_parse(const sdfd_url_args *args, int volume, sdfd_slice_params *out, char *err,
                     size_t cap, const char **argument)
{
    parse p = {args, err, cap, argument};
    *out = (sdfd_slice_params){.volume = volume, .size = SDFD_SLICE_DEFAULT_SIZE};
    int rc = sdfd_url_args_check(
        args, sdfd_op_get(volume ? SDFD_OP_VOLUME_SLICE : SDFD_OP_MESH_SLICE), err, cap, argument);
    if (rc || (rc = parse_plane(&p, out)) || (rc = parse_mode(&p, out)) ||
        (rc = parse_filter(&p, out)))
        return rc;
    const char *bounds = value_of(&p, "bounds"), *size = value_of(&p, "size"),
               *step = value_of(&p, "step"), *format = value_of(&p, "format");
    if (bounds) {
        double x[6];
        if (numbers(bounds, x, 6) || !(x[0] < x[3] && x[1] < x[4] && x[2] < x[5]))
            return refuse(&p, "bounds", "bounds must be x0,y0,z0,x1,y1,z1, finite, with x0 < x1, "
                          "y0 < y1 and z0 < z1");
        memcpy(out->lo, x, sizeof out->lo);
        memcpy(out->hi, x + 3, sizeof out->hi);
        out->has_bounds = 1;
    }
    if (size) {
        char *end;
        errno = 0;
        long s = strtol(size, &end, 10);
        if (*end || errno || s < 1 || s > SDFD_SLICE_MAX_SIZE)
            return refuse(&p, "size", "size must be an integer 1..%d (pixels of the longer "
                          "side), not '%.40s'", SDFD_SLICE_MAX_SIZE, size);
        out->size = (int)s;
    }
    if (step && (numbers(step, &out->step, 1) || !(out->step > 0)))
        return refuse(&p, "step", "step must be a positive finite number, not '%.40s'", step);
    if (format && strcasecmp(format, "png") && !(out->npy = !strcasecmp(format, "npy")))
        return refuse(&p, "format", "unknown format '%.40s' (png, npy)", format);
    return 0;
}

/* ---- the plane ---------------------------------------------------------------------------- */

static double dot(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The image's right (u) and up (v) directions for the parameters' plane: for an axis, the
 * two others in order (x: y up z; y: x and z; z: x and y); for a normal, the world axis
 * least along it, made perpendicular, and normal x u. */
static void basis(const sdfd_slice_params *p, double u[3], double v[3])
{
    static const int right_of[3] = {1, 0, 0}, up_of[3] = {2, 2, 1};
    memset(u, 0, 3 * sizeof *u);
    memset(v, 0, 3 * sizeof *v);
    if (p->axis >= 0) {
        u[right_of[p->axis]] = 1, v[up_of[p->axis]] = 1;
        return;
    }
    const double *n = p->normal;
    u[fabs(n[0]) < 0.9 ? 0 : 1] = 1;
    double d = dot(u, n), len = 0;
    for (int a = 0; a < 3; a++)
        u[a] -= d * n[a], len += u[a] * u[a];
    for (int a = 0; a < 3; a++)
        u[a] /= sqrt(len);
    v[0] = n[1] * u[2] - n[2] * u[1];
    v[1] = n[2] * u[0] - n[0] * u[2];
    v[2] = n[0] * u[1] - n[1] * u[0];
}

void sdfd_slice_layout(const sdfd_slice_params *p, const double box_lo[3],
                       const double box_hi[3], double margin, sdfd_slice_plane *out)
{
    double lo[3], hi[3], centre[3], u[3], v[3], grow = 0;
    for (int a = 0; a < 3 && !p->has_bounds; a++)
        grow = fmax(grow, margin * (box_hi[a] - box_lo[a]));
    for (int a = 0; a < 3; a++) {
        lo[a] = p->has_bounds ? p->lo[a] : box_lo[a] - grow;
        hi[a] = p->has_bounds ? p->hi[a] : box_hi[a] + grow;
        centre[a] = 0.5 * (lo[a] + hi[a]);
    }
    double origin[3];
    memcpy(origin, p->axis < 0 && p->has_origin ? p->origin : centre, sizeof origin);
    if (p->axis >= 0 && p->has_at)
        origin[p->axis] = p->at;
    basis(p, u, v);
    /* The bounds' corners seen in the plane: the image covers them all. */
    double umin = INFINITY, umax = -INFINITY, vmin = INFINITY, vmax = -INFINITY;
    for (int c = 0; c < 8; c++) {
        double corner[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]};
        for (int a = 0; a < 3; a++)
            corner[a] -= origin[a];
        double cu = dot(corner, u), cv = dot(corner, v);
        umin = fmin(umin, cu), umax = fmax(umax, cu), vmin = fmin(vmin, cv), vmax = fmax(vmax, cv);
    }
    double extent = fmax(umax - umin, vmax - vmin), h = extent / p->size;
    out->width = (umax - umin) >= (vmax - vmin) ? (size_t)p->size
                                                : (size_t)fmax(1, round((umax - umin) / h));
    out->height = (vmax - vmin) > (umax - umin) ? (size_t)p->size
                                                 : (size_t)fmax(1, round((vmax - vmin) / h));
    double uc = 0.5 * (umin + umax) - 0.5 * (double)(out->width - 1) * h;
    double vc = 0.5 * (vmin + vmax) + 0.5 * (double)(out->height - 1) * h;
    for (int a = 0; a < 3; a++) {
        out->first[a] = origin[a] + uc * u[a] + vc * v[a];
        out->right[a] = h * u[a];
        out->down[a] = -h * v[a];
    }
}

void sdfd_slice_points(const sdfd_slice_plane *plane, float *points)
{
    for (size_t j = 0, k = 0; j < plane->height; j++)
        for (size_t i = 0; i < plane->width; i++, k++)
            for (int a = 0; a < 3; a++)
                points[3 * k + a] = (float)(plane->first[a] + (double)i * plane->right[a] +
                                            (double)j * plane->down[a]);
}
