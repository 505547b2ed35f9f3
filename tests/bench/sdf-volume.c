/* sdf-volume - bake and evaluate volumes with libsdf directly, for tests that compare the
 * server's floats with the library's and for scripting:
 *   sdf-volume bake MESH|demo OUT [--format exr|npy|raw] [--resolution N | N,M,K]
 *                   [--order 0|1] [--encoding float32|packed32] [--H h] [--delta d]
 *                   [--normalize plane|gradient]
 *                   [--lo x,y,z --hi x,y,z] [--margin m] [--threads T]
 *   sdf-volume eval VOLUME.exr POINTS.npy OUT.npy [--gradient]
 *                   [--interpolation trilinear|nearest|hermite|default]   (default trilinear)
 *   sdf-volume ops VOLUME.exr OUT --op NAME=R [--op NAME=R ...] [--format exr|npy|raw]
 *                   [--solver sweep|sussman] [--iterations N] [--band B] [--strict]
 *                   [--threads T]
 *   sdf-volume mesh VOLUME.exr|VOLUME.npy OUT.ply|obj|stl|off [--iso x] [--cap]
 *                   [--threads T] [--repeat R] [--origin x,y,z] [--spacing x,y,z]
 * bake prints the volume's metadata (JSON) on stdout; eval writes float32 (N,) values, or
 * (N, 4) value and gradient; ops applies the field operations in order
 * (sdf_volume_apply_ops, with sdfd's defaults: sweep) and prints {"caveats": BITS,
 * "warning": "..."}; mesh extracts the surface (sdf_volume_extract) R times (default 1) and
 * prints {"vertices", "triangles", "seconds": the fastest}; an npy volume (float32, shape
 * (K, M, N)) has the origin and spacing given (default 0,0,0 and 1,1,1). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../common/files.h"
#include "../common/npyio.h"
#include "sdf/sdf.h"

static void die(const char *what, const char *why)
{
    fprintf(stderr, "sdf-volume: %s: %s\n", what, why);
    exit(1);
}

static void numbers(const char *s, double *out, int n, const char *flag)
{
    for (int i = 0; i < n; i++) {
        char *end;
        out[i] = strtod(s, &end);
        if (end == s || (i + 1 < n && *end != ','))
            die(flag, "expects comma-separated numbers");
        s = end + 1;
    }
}

static int bake(int argc, char **argv)
{
    if (argc < 4)
        die("bake", "needs MESH and OUT");
    sdf_mesh *mesh = NULL;
    sdf_diag diag;
    if (!strcmp(argv[2], "demo") ? sdf_mesh_create_demo(&mesh)
                                 : sdf_mesh_load_file(argv[2], NULL, &mesh, &diag))
        die(argv[2], "cannot load the mesh");
    sdf_bake_options o = {0};
    sdf_volume_file type = SDF_VOLUME_EXR;
    for (int i = 4; i < argc; i++) {
        const char *f = argv[i], *v = i + 1 < argc ? argv[++i] : NULL;
        if (!v)
            die(f, "needs a value");
        if (!strcmp(f, "--format")) {
            if (sdf_volume_file_from_name(v, &type))
                die(f, "exr, npy or raw");
        } else if (!strcmp(f, "--resolution")) {
            double d[3];
            if (strchr(v, ','))
                numbers(v, d, 3, f);
            else
                d[0] = d[1] = d[2] = atof(v);
            for (int a = 0; a < 3; a++)
                o.dims[a] = (size_t)d[a];
        } else if (!strcmp(f, "--order")) {
            o.order = atoi(v);
        } else if (!strcmp(f, "--encoding")) {
            if (sdf_encoding_from_name(v, &o.encoding))
                die(f, "float32 or packed32");
        } else if (!strcmp(f, "--H")) {
            o.fine_half = atoi(v);
        } else if (!strcmp(f, "--normalize")) {
            if (sdf_normalize_from_name(v, &o.normalize))
                die(f, "plane or gradient");
        } else if (!strcmp(f, "--delta")) {
            o.fine_spacing = atof(v);
        } else if (!strcmp(f, "--lo")) {
            numbers(v, o.lo, 3, f);
        } else if (!strcmp(f, "--hi")) {
            numbers(v, o.hi, 3, f);
        } else if (!strcmp(f, "--margin")) {
            o.margin = atof(v);
        } else if (!strcmp(f, "--threads")) {
            o.query.threads = atoi(v);
        } else {
            die(f, "unknown option");
        }
    }
    sdf_volume *v = NULL;
    if (sdf_volume_bake(mesh, &o, &v, &diag) || sdf_volume_save_file(v, type, argv[3], &diag))
        die(argv[3], diag.message);
    char json[1024];
    if (sdf_volume_describe_json(v, json, sizeof json) > 0)
        printf("%s\n", json);
    sdf_volume_destroy(v);
    sdf_mesh_release(mesh);
    return 0;
}

static int eval(int argc, char **argv)
{
    if (argc < 5)
        die("eval", "needs VOLUME.exr, POINTS.npy and OUT.npy");
    sdf_volume_filter filter = SDF_VOLUME_TRILINEAR;
    int gradient = 0;
    for (int i = 5; i < argc; i++) {
        if (!strcmp(argv[i], "--gradient"))
            gradient = 1;
        else if (!strcmp(argv[i], "--interpolation") && i + 1 < argc) {
            if (sdf_volume_filter_from_name(argv[++i], &filter))
                die(argv[i], "trilinear, nearest, hermite or default");
        }
        else
            die(argv[i], "unknown option");
    }
    sdf_volume *v = NULL;
    sdf_diag diag;
    if (sdf_volume_load_exr_file(argv[2], &v, &diag))
        die(argv[2], diag.message);
    size_t n;
    float *p = npy_load_points("sdf-volume", argv[3], &n);
    float *value = malloc((n + 1) * sizeof *value), *grad = malloc((3 * n + 1) * sizeof *grad);
    if (sdf_volume_eval(v, p, n, filter, value, gradient ? grad : NULL, NULL))
        die("eval", "failed");
    npy_write_results("sdf-volume", argv[4], n, gradient ? 4 : 1, value, grad);
    free(p), free(value), free(grad);
    sdf_volume_destroy(v);
    return 0;
}

/* --op NAME=R into *op. */
static void parse_op(const char *text, sdf_field_op *op)
{
    char name[32];
    const char *eq = strchr(text, '=');
    if (!eq || (size_t)(eq - text) >= sizeof name)
        die(text, "--op expects NAME=R");
    memcpy(name, text, (size_t)(eq - text));
    name[eq - text] = '\0';
    char *end;
    op->r = (float)strtod(eq + 1, &end); /* as sdfd reads a JSON number */
    if (sdf_field_op_from_name(name, &op->kind) || end == eq + 1 || *end)
        die(text, "--op expects NAME=R with NAME redistance, offset, round, fillet or smooth");
}

static int ops(int argc, char **argv)
{
    if (argc < 4)
        die("ops", "needs VOLUME.exr and OUT");
    sdf_field_op list[SDF_FIELD_MAX_OPS];
    size_t count = 0;
    sdf_field_options o = {.solver = SDF_FIELD_SWEEP};
    sdf_volume_file type = SDF_VOLUME_EXR;
    for (int i = 4; i < argc; i++) {
        const char *f = argv[i];
        if (!strcmp(f, "--strict")) {
            o.strict = 1;
            continue;
        }
        const char *v = i + 1 < argc ? argv[++i] : NULL;
        if (!v)
            die(f, "needs a value");
        if (!strcmp(f, "--op")) {
            if (count == SDF_FIELD_MAX_OPS)
                die(f, "too many operations");
            parse_op(v, &list[count++]);
        } else if (!strcmp(f, "--format")) {
            if (sdf_volume_file_from_name(v, &type))
                die(f, "exr, npy or raw");
        } else if (!strcmp(f, "--solver")) {
            if (sdf_field_solver_from_name(v, &o.solver))
                die(f, "sweep or sussman");
        } else if (!strcmp(f, "--iterations")) {
            o.iterations = atoi(v);
        } else if (!strcmp(f, "--band")) {
            o.band = atof(v);
        } else if (!strcmp(f, "--threads")) {
            o.threads = atoi(v);
        } else {
            die(f, "unknown option");
        }
    }
    sdf_volume *in = NULL, *out = NULL;
    sdf_diag diag;
    unsigned caveats = 0;
    if (sdf_volume_load_exr_file(argv[2], &in, &diag))
        die(argv[2], diag.message);
    if (sdf_volume_apply_ops(in, list, count, &o, &out, &caveats, &diag))
        die("ops", diag.message);
    printf("{\"caveats\": %u, \"warning\": \"%s\"}\n", caveats, caveats ? diag.message : "");
    sdf_diag save;
    if (sdf_volume_save_file(out, type, argv[3], &save))
        die(argv[3], save.message);
    sdf_volume_destroy(in);
    sdf_volume_destroy(out);
    return 0;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int ends_with(const char *s, const char *tail)
{
    size_t n = strlen(s), m = strlen(tail);
    return n >= m && !strcmp(s + n - m, tail);
}

static sdf_volume *load_volume(const char *path, const double origin[3], const double spacing[3])
{
    sdf_volume *v = NULL;
    sdf_diag diag;
    if (ends_with(path, ".exr")) {
        if (sdf_volume_load_exr_file(path, &v, &diag))
            die(path, diag.message);
        return v;
    }
    size_t size;
    char *bytes = read_whole_file(path, &size);
    sdf_npy_info npy;
    if (!bytes || sdf_npy_parse(bytes, size, &npy, &diag) || npy.ndim != 3 ||
        npy.dtype != SDF_NPY_F32)
        die(path, "not a float32 npy array of shape (K, M, N)");
    sdf_volume_info in = {.dims = {npy.shape[2], npy.shape[1], npy.shape[0]}};
    memcpy(in.origin, origin, sizeof in.origin);
    memcpy(in.spacing, spacing, sizeof in.spacing);
    if (sdf_volume_create(&in, bytes + npy.data_offset, &v, &diag))
        die(path, diag.message);
    free(bytes);
    return v;
}

static int mesh(int argc, char **argv)
{
    if (argc < 4)
        die("mesh", "needs VOLUME and OUT");
    sdf_extract_options o = {0};
    double origin[3] = {0, 0, 0}, spacing[3] = {1, 1, 1};
    int repeat = 1;
    for (int i = 4; i < argc; i++) {
        if (!strcmp(argv[i], "--cap"))
            o.cap = 1;
        else if (!strcmp(argv[i], "--iso") && i + 1 < argc)
            o.iso = strtod(argv[++i], NULL);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            o.threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--repeat") && i + 1 < argc)
            repeat = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--origin") && i + 1 < argc)
            numbers(argv[++i], origin, 3, "--origin");
        else if (!strcmp(argv[i], "--spacing") && i + 1 < argc)
            numbers(argv[++i], spacing, 3, "--spacing");
        else
            die(argv[i], "unknown option");
    }
    sdf_format format;
    const char *dot = strrchr(argv[3], '.');
    if (!dot || sdf_format_from_name(dot + 1, &format) || format == SDF_FORMAT_AUTO)
        die(argv[3], "OUT must end in .ply, .obj, .stl or .off");
    sdf_volume *v = load_volume(argv[2], origin, spacing);
    sdf_surface *s = NULL;
    sdf_diag diag;
    double best = 1e30;
    for (int r = 0; r < (repeat > 0 ? repeat : 1); r++) {
        sdf_surface_destroy(s);
        double t0 = now();
        if (sdf_volume_extract(v, &o, &s, &diag))
            die("mesh", diag.message);
        best = now() - t0 < best ? now() - t0 : best;
    }
    size_t nv, nt;
    const float *p = sdf_surface_vertices(s, &nv);
    const uint32_t *t = sdf_surface_triangles(s, &nt);
    size_t cap = sdf_mesh_write_bound(nv, nt, format);
    char *buf = malloc(cap + 1);
    size_t n = buf ? sdf_mesh_write(p, nv, t, nt, format, buf, cap) : 0;
    FILE *f = fopen(argv[3], "wb");
    if (!n || !f || fwrite(buf, 1, n, f) != n || fclose(f))
        die(argv[3], "cannot write it");
    printf("{\"vertices\": %zu, \"triangles\": %zu, \"seconds\": %.6f}\n", nv, nt, best);
    free(buf);
    sdf_surface_destroy(s);
    sdf_volume_destroy(v);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc >= 2 && !strcmp(argv[1], "bake"))
        return bake(argc, argv);
    if (argc >= 2 && !strcmp(argv[1], "eval"))
        return eval(argc, argv);
    if (argc >= 2 && !strcmp(argv[1], "ops"))
        return ops(argc, argv);
    if (argc >= 2 && !strcmp(argv[1], "mesh"))
        return mesh(argc, argv);
    fprintf(stderr, "usage: sdf-volume bake MESH|demo OUT [options] | eval VOLUME.exr POINTS.npy "
            "OUT.npy | ops VOLUME.exr OUT --op NAME=R [options] | mesh VOLUME OUT [options]\n");
    return 2;
}
