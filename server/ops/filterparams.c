/* filterparams.c - filter parameters from JSON or URL arguments (see filterparams.h). */
#include "ops/filterparams.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <cjson/cJSON.h>

#include "core/errors.h"

enum kind { NUMBER, COUNT, FLAG, KERNEL, SEED };

/* Each name, its kind, and where it goes in sdf_filter_options (a double for NUMBER, an int
 * for COUNT and FLAG, the sdf_kernel for KERNEL, the uint64_t for SEED). */
#define AT(member) offsetof(sdf_filter_options, member)
static const struct field {
    const char *name;
    enum kind kind;
    size_t offset;
} fields[] = {
    {"kernel", KERNEL, AT(kernel)},      {"cap", NUMBER, AT(cap)},
    {"a", NUMBER, AT(a)},                {"b", NUMBER, AT(b)},
    {"samples", COUNT, AT(samples)},     {"min_samples", COUNT, AT(min_samples)},
    {"medial", NUMBER, AT(medial)},      {"grid", FLAG, AT(grid)},
    {"unsigned", FLAG, AT(unsigned_integrand)},
    {"allow_wide_bump", FLAG, AT(allow_wide_bump)},
    {"sample_gradient", FLAG, AT(sample_gradient)},
    {"seed", SEED, AT(seed)},
};
#define FIELDS (sizeof fields / sizeof fields[0])

/* The smoothing volume's URL arguments (a JSON body nests them in "smooth"). */
enum { SPHERE, BOX, MESH, DEPTH, SCALE, SMOOTH_NAMES };
static const char *const smooth_names[SMOOTH_NAMES] = {"smooth_sphere", "smooth_box",
                                                       "smooth_mesh", "smooth_depth",
                                                       "smooth_scale"};

#define MAX_SEED 9007199254740992.0 /* 2^53: every integer up to it is exact in JSON */

static int bad(char *err, size_t cap, const char *fmt, const char *name)
{
    snprintf(err, cap, fmt, name);
    return SDF_EINVAL;
}

/* Store one value. `number` for NUMBER/COUNT/SEED/FLAG, `text` for KERNEL. */
static int store(sdf_filter_options *f, const struct field *fd, double number, const char *text,
                 char *err, size_t cap)
{
    char *at = (char *)f + fd->offset;
    switch (fd->kind) {
    case KERNEL:
        if (!strcasecmp(text, "gaussian"))
            *(sdf_kernel *)at = SDF_KERNEL_GAUSSIAN;
        else if (!strcasecmp(text, "bump"))
            *(sdf_kernel *)at = SDF_KERNEL_BUMP;
        else
            return bad(err, cap, "filter kernel must be \"gaussian\" or \"bump\", not \"%.40s\"",
                       text);
        return 0;
    case NUMBER: /* cap, a, b, medial: the library reads 0 as "the default", so it is
                  * refused here rather than silently replaced */
        if (!isfinite(number) || !(number > 0))
            return bad(err, cap, "filter %s must be a positive finite number", fd->name);
        *(double *)at = number;
        return 0;
    case COUNT:
        if (number != floor(number) || number < 1 || number > SDF_FILTER_MAX_SAMPLES)
            return bad(err, cap, "filter %s must be an integer 1..4096", fd->name);
        *(int *)at = (int)number;
        return 0;
    case SEED:
        if (number != floor(number) || number < 0 || number > MAX_SEED)
            return bad(err, cap, "filter seed must be an integer 0..2^53", NULL);
        *(uint64_t *)at = (uint64_t)number;
        return 0;
    case FLAG:
        *(int *)at = number != 0;
        return 0;
    }
    return SDF_EINVAL;
}

static const struct field *find(const char *name)
{
    for (size_t i = 0; i < FIELDS; i++)
        if (!strcmp(fields[i].name, name))
            return &fields[i];
    return NULL;
}

/* Fill `values` from a JSON array of exactly n finite numbers. */
static int json_numbers(const cJSON *a, double *values, int n)
{
    if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != n)
        return -1;
    int i = 0;
    for (const cJSON *e = a->child; e; e = e->next, i++) {
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble))
            return -1;
        values[i] = e->valuedouble;
    }
    return 0;
}

static int set_volume_numbers(sdf_smoothing_volume *v, sdf_volume_shape shape, const double *x)
{
    v->shape = shape;
    if (shape == SDF_VOLUME_SPHERE) {
        memcpy(v->center, x, sizeof v->center);
        v->radius = x[3];
    } else {
        memcpy(v->lo, x, sizeof v->lo);
        memcpy(v->hi, x + 3, sizeof v->hi);
    }
    return 0;
}

static int copy_name(char *dst, const char *name, char *err, size_t cap)
{
    size_t n = strlen(name);
    if (n == 0 || n > SDFD_VOLUME_NAME_MAX)
        return bad(err, cap, "smoothing mesh name must be 1..255 characters", NULL);
    memcpy(dst, name, n + 1);
    return 0;
}

const char *sdfd_json_repeated_key(const cJSON *object)
{
    for (const cJSON *a = object->child; a; a = a->next)
        for (const cJSON *b = object->child; b != a; b = b->next)
            if (a->string && b->string && !strcmp(a->string, b->string))
                return a->string;
    return NULL;
}

int sdfd_json_body_object(const char *text, size_t len, cJSON **root, char *err, size_t cap)
{
    *root = cJSON_ParseWithLength(text, len);
    if (!*root) {
        snprintf(err, cap, "the body is not valid JSON");
        return SDFD_ESYNTAX;
    }
    const char *twice = NULL;
    if (!cJSON_IsObject(*root))
        snprintf(err, cap, "the body must be a JSON object");
    else if ((twice = sdfd_json_repeated_key(*root)))
        snprintf(err, cap, "'%.40s' is given twice", twice);
    else
        return 0;
    cJSON_Delete(*root);
    *root = NULL;
    return SDF_EINVAL;
}

static int json_smooth(const cJSON *o, sdf_filter_options *f, char *volume_mesh, char *err,
                       size_t cap)
{
    if (!cJSON_IsObject(o))
        return bad(err, cap, "filter smooth must be an object", NULL);
    const char *twice = sdfd_json_repeated_key(o);
    if (twice)
        return bad(err, cap, "smooth \"%.40s\" is given twice", twice);
    int shapes = 0;
    for (const cJSON *item = o->child; item; item = item->next) {
        const char *k = item->string ? item->string : "";
        double x[6];
        if (!strcmp(k, "sphere") || !strcmp(k, "box")) {
            int sphere = k[0] == 's', n = sphere ? 4 : 6;
            if (json_numbers(item, x, n))
                return bad(err, cap, sphere ? "smooth sphere must be [x, y, z, radius]"
                                            : "smooth box must be [x0, y0, z0, x1, y1, z1]", NULL);
            set_volume_numbers(&f->smooth, sphere ? SDF_VOLUME_SPHERE : SDF_VOLUME_BOX, x);
            shapes++;
        } else if (!strcmp(k, "mesh")) {
            if (!cJSON_IsString(item) || copy_name(volume_mesh, item->valuestring, err, cap))
                return bad(err, cap, "smooth mesh must be the name of a loaded mesh", NULL);
            f->smooth.shape = SDF_VOLUME_MESH;
            shapes++;
        } else if (!strcmp(k, "depth") || !strcmp(k, "scale")) {
            if (!cJSON_IsNumber(item) || !isfinite(item->valuedouble) || !(item->valuedouble > 0))
                return bad(err, cap, "smooth %s must be a positive finite number", k);
            *(k[0] == 'd' ? &f->smooth.depth : &f->smooth.scale) = item->valuedouble;
        } else {
            return bad(err, cap, "unknown smooth parameter \"%.40s\" (sphere, box, mesh, depth, "
                       "scale)", k);
        }
    }
    if (shapes != 1)
        return bad(err, cap, "filter smooth needs exactly one of sphere, box or mesh", NULL);
    return 0;
}

int sdfd_filter_from_json(const char *text, size_t len, sdf_filter_options *out,
                          char volume_mesh[SDFD_VOLUME_NAME_MAX + 1], char *err, size_t cap)
{
    *out = (sdf_filter_options){0};
    volume_mesh[0] = 0;
    cJSON *root = cJSON_ParseWithLength(text, len);
    if (!cJSON_IsObject(root)) {
        cJSON_Delete(root);
        return bad(err, cap, "\"filter\" must be a JSON object", NULL);
    }
    const char *twice = sdfd_json_repeated_key(root);
    int rc = twice ? bad(err, cap, "filter \"%.40s\" is given twice", twice) : 0;
    for (cJSON *item = root->child; item && !rc; item = item->next) {
        const struct field *fd = item->string ? find(item->string) : NULL;
        if (item->string && !strcmp(item->string, "smooth")) {
            rc = json_smooth(item, out, volume_mesh, err, cap);
        } else if (!fd) {
            rc = bad(err, cap, "unknown filter parameter \"%.40s\" (kernel, cap, a, b, samples, "
                     "min_samples, medial, grid, unsigned, allow_wide_bump, seed, smooth)",
                     item->string ? item->string : "");
        } else if (fd->kind == KERNEL) {
            rc = cJSON_IsString(item) ? store(out, fd, 0, item->valuestring, err, cap)
                                      : bad(err, cap, "filter %s must be a string", fd->name);
        } else if (fd->kind == FLAG) {
            rc = cJSON_IsBool(item) ? store(out, fd, cJSON_IsTrue(item), NULL, err, cap)
                                    : bad(err, cap, "filter %s must be true or false", fd->name);
        } else {
            rc = cJSON_IsNumber(item) ? store(out, fd, item->valuedouble, NULL, err, cap)
                                      : bad(err, cap, "filter %s must be a number", fd->name);
        }
    }
    cJSON_Delete(root);
    return rc;
}

/* "x,y,z,..." -> exactly n finite numbers. */
static int list_numbers(const char *v, double *x, int n)
{
    for (int i = 0; i < n; i++) {
        char *end;
        errno = 0;
        x[i] = strtod(v, &end);
        if (end == v || errno || !isfinite(x[i]) || *end != (i + 1 < n ? ',' : '\0'))
            return -1;
        v = end + 1;
    }
    return 0;
}

static int string_smooth(const char *(*lookup)(void *ctx, const char *name), void *ctx,
                         sdf_filter_options *f, char *volume_mesh, char *err, size_t cap)
{
    const char *sphere = lookup(ctx, smooth_names[SPHERE]), *box = lookup(ctx, smooth_names[BOX]),
               *mesh = lookup(ctx, smooth_names[MESH]), *depth = lookup(ctx, smooth_names[DEPTH]),
               *scale = lookup(ctx, smooth_names[SCALE]);
    int shapes = !!sphere + !!box + !!mesh;
    if (!shapes && !depth && !scale)
        return 0;
    if (shapes != 1)
        return bad(err, cap, "give exactly one of smooth_sphere, smooth_box or smooth_mesh", NULL);
    double x[6];
    if (sphere && list_numbers(sphere, x, 4))
        return bad(err, cap, "smooth_sphere must be x,y,z,radius", NULL);
    if (box && list_numbers(box, x, 6))
        return bad(err, cap, "smooth_box must be x0,y0,z0,x1,y1,z1", NULL);
    if (sphere || box)
        set_volume_numbers(&f->smooth, sphere ? SDF_VOLUME_SPHERE : SDF_VOLUME_BOX, x);
    if (mesh) {
        if (copy_name(volume_mesh, mesh, err, cap))
            return SDF_EINVAL;
        f->smooth.shape = SDF_VOLUME_MESH;
    }
    const char *values[2] = {depth, scale};
    double *dst[2] = {&f->smooth.depth, &f->smooth.scale};
    for (int i = 0; i < 2; i++)
        if (values[i] && (list_numbers(values[i], dst[i], 1) || !(*dst[i] > 0)))
            return bad(err, cap, "smooth_%s must be a positive finite number",
                       i ? "scale" : "depth");
    return 0;
}

int sdfd_filter_from_strings(const char *(*lookup)(void *ctx, const char *name), void *ctx,
                             sdf_filter_options *out, char volume_mesh[SDFD_VOLUME_NAME_MAX + 1],
                             char *err, size_t cap)
{
    *out = (sdf_filter_options){0};
    volume_mesh[0] = 0;
    for (size_t i = 0; i < FIELDS; i++) {
        const struct field *fd = &fields[i];
        const char *v = lookup(ctx, fd->name);
        if (!v)
            continue;
        int rc;
        if (fd->kind == KERNEL) {
            rc = store(out, fd, 0, v, err, cap);
        } else if (fd->kind == FLAG) {
            int on = !strcmp(v, "1") || !strcasecmp(v, "true");
            int off = !strcmp(v, "0") || !strcasecmp(v, "false");
            rc = on || off ? store(out, fd, on, NULL, err, cap)
                           : bad(err, cap, "filter %s must be true, false, 1 or 0", fd->name);
        } else {
            char *end;
            errno = 0;
            double number = strtod(v, &end);
            rc = *v && !*end && !errno ? store(out, fd, number, NULL, err, cap)
                                      : bad(err, cap, "filter %s must be a number", fd->name);
        }
        if (rc)
            return rc;
    }
    return string_smooth(lookup, ctx, out, volume_mesh, err, cap);
}

const char *sdfd_filter_url_name(size_t i)
{
    if (i < FIELDS)
        return fields[i].name;
    return i < FIELDS + SMOOTH_NAMES ? smooth_names[i - FIELDS] : NULL;
}

int sdfd_filter_is_url_name(const char *name)
{
    for (size_t i = 0; sdfd_filter_url_name(i); i++)
        if (!strcmp(sdfd_filter_url_name(i), name))
            return 1;
    return 0;
}
