/* commands.c - sdfq's subcommands but bake (commands.h). Queries go over the binary
 * protocol, split into requests of at most --batch points (and the server's max_points)
 * pipelined on one connection, each answer landing in its place of one result array; the
 * rest are single HTTP requests. */
#include "commands.h"

#include <cJSON.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "http.h"
#include "points.h"
#include "sdfclient.h"

#define WINDOW 64 /* requests kept in flight: the server works on at most 64 per connection */

/* ---- the binary connection --------------------------------------------------------------- */

/* What to try when TLS, or its absence, is the likely cause of `rc`. */
static const char *tls_hint(const sdfq_server *srv, int rc)
{
    if (rc == SDFC_ETLS)
        return " (is its binary port plain? then leave out --bin-tls)";
    if (rc == SDFC_ECERT)
        return srv->cacert ? " (--cacert names the CA that signed it?)"
                           : " (pass the CA that signed it with --cacert)";
    if (rc == SDFC_ECLOSED && !srv->bin_tls)
        return " (if its binary port speaks TLS, pass --bin-tls)";
    return "";
}

/* Report a libsdfclient failure; the exit code. */
static int bin_fail(const sdfq_server *srv, sdfc_client *c, int rc, const char *context)
{
    const sdfc_server_err *e = sdfc_server_error(c);
    if (e && e->code[0]) {
        fprintf(stderr, "sdfq: server: %d %s: %s%s\n", e->status, e->code, e->message,
                context ? context : "");
        return SDFQ_REFUSED;
    }
    const char *proto = srv->bin_tls ? "binary protocol over TLS" : "binary protocol";
    if (rc == SDFC_ECONNECT || rc == SDFC_EIO)
        fprintf(stderr, "sdfq: cannot connect to %s:%d (%s): %s\n", srv->bin_host,
                srv->bin_port, proto, errno ? strerror(errno) : sdfc_strerror(rc));
    else if (rc == SDFC_EINVAL && srv->bin_tls)
        fprintf(stderr, "sdfq: the CA file %s holds no PEM certificate\n",
                srv->cacert ? srv->cacert : "(the system's)");
    else
        fprintf(stderr, "sdfq: %s:%d (%s): %s%s\n", srv->bin_host, srv->bin_port, proto,
                sdfc_strerror(rc), tls_hint(srv, rc));
    return SDFQ_CONNECT;
}

/* Connect, authenticate with the token if one is set, learn the limits. */
static int bin_open(const sdfq_server *srv, sdfc_client **out, sdfc_hello_info *hello)
{
    /* the points and result arrays outlive the connection, so it may re-send */
    sdfc_options o = {.reply_timeout_ms = srv->timeout_ms, .tls = srv->bin_tls,
                      .ca_file = srv->bin_tls ? srv->cacert : NULL, .resend = 1};
    errno = 0;
    int rc = sdfc_connect(srv->bin_host, srv->bin_port, &o, out);
    if (rc)
        return bin_fail(srv, NULL, rc, NULL);
    if (srv->token && (rc = sdfc_auth(*out, srv->token, strlen(srv->token))))
        goto fail;
    if ((rc = sdfc_hello(*out, hello)))
        goto fail;
    return 0;
fail:
    rc = bin_fail(srv, *out, rc, NULL);
    sdfc_close(*out);
    return rc;
}

/* ---- query and query-volume -------------------------------------------------------------- */

typedef struct query_job {
    const char *name;
    int volume;            /* VOLUME_QUERY instead of QUERY */
    sdfc_mode mode;        /* QUERY's mode; a volume's: SIGNED or GRADIENT */
    sdfc_sign sign;
    sdfc_interpolation interpolation; /* a volume's */
    sdfc_filter filter;
    size_t batch;
} query_job;

static int send_one(sdfc_client *c, const query_job *j, const float *p, uint32_t n, void *out,
                    uint32_t *id)
{
    size_t size = sdfc_result_size(j->mode, n);
    if (j->volume)
        return sdfc_send_volume_query(c, j->name, j->mode == SDFC_GRADIENT, j->interpolation, p,
                                      n, out, size, id);
    return sdfc_send_query(c, j->name, j->mode, j->sign, &j->filter, p, n, out, size, id);
}

/* The points of request `id`, for an error message: ids are given out in order, so the
 * k-th query has id first_id + k. */
static void batch_context(char *dst, size_t cap, const query_job *j, size_t total,
                          uint32_t first_id, uint32_t id)
{
    size_t first = (size_t)(id - first_id) * j->batch;
    size_t last = first + j->batch < total ? first + j->batch : total;
    if (total > j->batch)
        snprintf(dst, cap, " (in the request for points %zu..%zu; its point numbers count from "
                 "%zu)", first, last - 1, first);
    else
        dst[0] = 0;
}

static int run_queries(const sdfq_server *srv, const query_job *j, const sdfq_points *pts,
                       uint32_t *words)
{
    sdfc_client *c;
    sdfc_hello_info hello;
    int rc = bin_open(srv, &c, &hello);
    if (rc)
        return rc;
    query_job jb = *j;
    if (jb.batch > hello.max_points)
        jb.batch = hello.max_points ? hello.max_points : 1;
    size_t sent = 0, w = sdfc_words(jb.mode);
    uint32_t id = 0, first_id = 0;
    do {
        size_t n = pts->count - sent < jb.batch ? pts->count - sent : jb.batch;
        if (sdfc_in_flight(c) >= WINDOW && (rc = sdfc_wait_any(c, &id)))
            break;
        if ((rc = send_one(c, &jb, pts->xyz + 3 * sent, (uint32_t)n, words + w * sent, &id)))
            break;
        if (sent == 0)
            first_id = id;
        sent += n;
    } while (sent < pts->count);
    while (!rc && sdfc_in_flight(c) > 0)
        rc = sdfc_wait_any(c, &id);
    if (rc) {
        char context[160];
        batch_context(context, sizeof context, &jb, pts->count, first_id, id);
        rc = bin_fail(srv, c, rc, context);
    }
    sdfc_close(c);
    return rc;
}

static const char *columns(const query_job *j)
{
    if (j->volume)
        return j->mode == SDFC_GRADIENT ? "value,gx,gy,gz" : "value";
    static const char *const names[] = {"distance", "distance", "distance,gx,gy,gz",
                                        "distance,cx,cy,cz,triangle", "g", "g,gx,gy,gz"};
    return names[j->mode];
}

static int run_and_write(const sdfq_server *srv, const sdfq_args *a, const query_job *j)
{
    const char *in = a->npos > 1 ? a->pos[1] : "-";
    const char *out = sdfq_opt_value(a, "o") ? sdfq_opt_value(a, "o") : "-";
    sdfq_points pts;
    int rc = sdfq_read_points(in, &pts);
    if (rc)
        return rc;
    size_t w = sdfc_words(j->mode);
    uint32_t *words = malloc(pts.count ? 4 * w * pts.count : 1);
    if (!words) {
        fprintf(stderr, "sdfq: out of memory for %zu results\n", pts.count);
        sdfq_points_free(&pts);
        return SDFQ_INPUT;
    }
    rc = run_queries(srv, j, &pts, words);
    if (!rc) {
        const char *f = sdfq_opt_value(a, "output-format");
        sdfq_out_format format = f ? (!strcmp(f, "npy") ? SDFQ_OUT_NPY : SDFQ_OUT_CSV)
                                   : sdfq_out_format_of(out);
        rc = sdfq_write_results(out, format, columns(j), (unsigned)w, words, pts.count);
    }
    free(words);
    sdfq_points_free(&pts);
    return rc;
}

static int check_common(const sdfq_args *a, query_job *j)
{
    long batch = 65536;
    const char *f = sdfq_opt_value(a, "output-format");
    if (a->npos < 1 || a->npos > 2) {
        fprintf(stderr, "sdfq %s: needs a name and at most one points file (see --help)\n", a->cmd);
        return SDFQ_USAGE;
    }
    if (f && strcmp(f, "npy") && strcmp(f, "csv")) {
        fprintf(stderr, "sdfq %s: --output-format is npy or csv, not '%s'\n", a->cmd, f);
        return SDFQ_USAGE;
    }
    if (sdfq_opt_long(a, "batch", 1, 1L << 30, &batch))
        return SDFQ_USAGE;
    j->name = a->pos[0];
    j->batch = (size_t)batch;
    return 0;
}

static int parse_filter(const sdfq_args *a, sdfc_filter *f)
{
    long samples = 0;
    const char *kernel = sdfq_opt_value(a, "kernel");
    if (sdfq_opt_long(a, "samples", 0, 4096, &samples) || sdfq_opt_u64(a, "seed", &f->seed) ||
        sdfq_opt_double(a, "cap", &f->cap))
        return SDFQ_USAGE;
    f->samples = (uint32_t)samples;
    if (kernel && strcmp(kernel, "gaussian") && strcmp(kernel, "bump")) {
        fprintf(stderr, "sdfq query: --kernel is gaussian or bump, not '%s'\n", kernel);
        return SDFQ_USAGE;
    }
    f->kernel = kernel && !strcmp(kernel, "bump");
    return 0;
}

int sdfq_cmd_query(const sdfq_server *srv, const sdfq_args *a)
{
    query_job j = {0};
    int rc = check_common(a, &j);
    if (rc)
        return rc;
    const char *mode = sdfq_opt_value(a, "mode"), *sign = sdfq_opt_value(a, "sign");
    if (mode && sdfc_mode_from_name(mode, &j.mode)) {
        fprintf(stderr, "sdfq query: unknown --mode '%s' (signed, distance, gradient, closest, "
                "filtered, filtered-gradient)\n", mode);
        return SDFQ_USAGE;
    }
    if (sign && sdfc_sign_from_name(sign, &j.sign)) {
        fprintf(stderr, "sdfq query: unknown --sign '%s' (auto, pseudonormal, winding, raycast, "
                "none)\n", sign);
        return SDFQ_USAGE;
    }
    if ((rc = parse_filter(a, &j.filter)))
        return rc;
    return run_and_write(srv, a, &j);
}

int sdfq_cmd_query_volume(const sdfq_server *srv, const sdfq_args *a)
{
    query_job j = {.volume = 1, .interpolation = SDFC_INTERP_DEFAULT};
    int rc = check_common(a, &j);
    if (rc)
        return rc;
    const char *interp = sdfq_opt_value(a, "interpolation");
    if (interp && sdfc_interpolation_from_name(interp, &j.interpolation)) {
        fprintf(stderr, "sdfq query-volume: --interpolation is default, trilinear, nearest or "
                "hermite, not '%s'\n", interp);
        return SDFQ_USAGE;
    }
    j.mode = sdfq_opt_value(a, "gradient") ? SDFC_GRADIENT : SDFC_SIGNED;
    return run_and_write(srv, a, &j);
}

int sdfq_cmd_meshes(const sdfq_server *srv, const sdfq_args *a)
{
    static const char *const signs[] = {"auto", "pseudonormal", "winding", "raycast", "none"};
    if (a->npos) {
        fprintf(stderr, "sdfq meshes: takes no arguments\n");
        return SDFQ_USAGE;
    }
    sdfc_client *c;
    sdfc_hello_info hello;
    int rc = bin_open(srv, &c, &hello);
    if (rc)
        return rc;
    size_t count = 0;
    sdfc_mesh *list = NULL;
    rc = sdfc_list_meshes(c, NULL, 0, &count);
    if (!rc && count && !(list = calloc(count, sizeof *list)))
        rc = SDFC_ENOMEM;
    if (!rc && count)
        rc = sdfc_list_meshes(c, list, count, &count); /* a mesh added since is left out */
    for (size_t i = 0; !rc && i < count; i++)
        printf("%s\t%llu\t%s\t%s\n", list[i].name, (unsigned long long)list[i].triangles,
               list[i].closed ? "closed" : "open",
               list[i].auto_sign >= 0 && list[i].auto_sign < 5 ? signs[list[i].auto_sign] : "?");
    if (rc)
        rc = bin_fail(srv, c, rc, NULL);
    free(list);
    sdfc_close(c);
    return rc;
}

/* ---- HTTP -------------------------------------------------------------------------------- */

static int one_name(const sdfq_args *a, int expect)
{
    if (a->npos != expect) {
        fprintf(stderr, "sdfq %s: needs %d argument%s (see sdfq %s --help)\n", a->cmd, expect,
                expect == 1 ? "" : "s", a->cmd);
        return SDFQ_USAGE;
    }
    return 0;
}

/* "/v1/<collection>/<escaped name><suffix>" into a malloc'ed string. */
static char *route(const char *collection, const char *name, const char *suffix)
{
    char *e = sdfq_escape(name);
    size_t n = e ? strlen(collection) + strlen(e) + strlen(suffix) + 8 : 0;
    char *path = n ? malloc(n) : NULL;
    if (path)
        snprintf(path, n, "/v1/%s/%s%s", collection, e, suffix);
    free(e);
    if (!path)
        fprintf(stderr, "sdfq: out of memory\n");
    return path;
}

int sdfq_cmd_upload(const sdfq_server *srv, const sdfq_args *a)
{
    int rc = one_name(a, 2);
    if (rc)
        return rc;
    const char *format = sdfq_opt_value(a, "format");
    FILE *f = fopen(a->pos[1], "rb");
    long long size = -1;
    if (f && !fseek(f, 0, SEEK_END))
        size = ftell(f), rewind(f);
    if (!f || size < 0) {
        fprintf(stderr, "sdfq: cannot read %s: %s\n", a->pos[1], strerror(errno));
        if (f)
            fclose(f);
        return SDFQ_INPUT;
    }
    char suffix[64] = "";
    if (format)
        snprintf(suffix, sizeof suffix, "?format=%.40s", format);
    char *path = route("meshes", a->pos[0], suffix);
    sdfq_request req = {.method = "PUT", .path = path, .upload = f, .upload_size = size,
                        .content_type = "application/octet-stream"};
    sdfq_reply reply;
    rc = path ? sdfq_http(srv, &req, &reply) : SDFQ_CONNECT;
    if (!rc) {
        printf("%s\n", reply.body ? reply.body : "");
        sdfq_reply_free(&reply);
    }
    free(path);
    fclose(f);
    return rc;
}

static const char *download_format(const sdfq_args *a, const char *out)
{
    const char *format = sdfq_opt_value(a, "format");
    if (format)
        return format;
    size_t n = strlen(out);
    if (n > 4 && !strcmp(out + n - 4, ".npy"))
        return "npy";
    if (n > 4 && !strcmp(out + n - 4, ".raw"))
        return "raw";
    return "exr";
}

int sdfq_cmd_download(const sdfq_server *srv, const sdfq_args *a)
{
    int rc = one_name(a, 1);
    const char *out = sdfq_opt_value(a, "o");
    if (rc || !out) {
        if (!rc)
            fprintf(stderr, "sdfq download: needs -o FILE (or -o - for standard output)\n");
        return SDFQ_USAGE;
    }
    const char *format = download_format(a, out);
    if (strcmp(format, "exr") && strcmp(format, "npy") && strcmp(format, "raw")) {
        fprintf(stderr, "sdfq download: --format is exr, npy or raw, not '%s'\n", format);
        return SDFQ_USAGE;
    }
    char suffix[32];
    snprintf(suffix, sizeof suffix, "/data?format=%s", format);
    char *path = route("volumes", a->pos[0], suffix);
    sdfq_request req = {.method = "GET", .path = path, .save_to = out};
    sdfq_reply reply;
    rc = path ? sdfq_http(srv, &req, &reply) : SDFQ_CONNECT;
    if (!rc)
        sdfq_reply_free(&reply);
    free(path);
    return rc;
}

int sdfq_cmd_delete(const sdfq_server *srv, const sdfq_args *a)
{
    if (a->npos < 1) {
        fprintf(stderr, "sdfq delete: needs at least one name (see sdfq delete --help)\n");
        return SDFQ_USAGE;
    }
    int volume = sdfq_opt_value(a, "volume") != NULL, job = sdfq_opt_value(a, "job") != NULL;
    if (volume && job) {
        fprintf(stderr, "sdfq delete: --volume and --job exclude each other\n");
        return SDFQ_USAGE;
    }
    const char *collection = volume ? "volumes" : job ? "jobs" : "meshes";
    for (int i = 0; i < a->npos; i++) {
        char *path = route(collection, a->pos[i], "");
        sdfq_request req = {.method = "DELETE", .path = path};
        sdfq_reply reply;
        int rc = path ? sdfq_http(srv, &req, &reply) : SDFQ_CONNECT;
        free(path);
        if (rc)
            return rc;
        sdfq_reply_free(&reply);
    }
    return 0;
}

int sdfq_cmd_volumes(const sdfq_server *srv, const sdfq_args *a)
{
    if (a->npos) {
        fprintf(stderr, "sdfq volumes: takes no arguments\n");
        return SDFQ_USAGE;
    }
    sdfq_request req = {.method = "GET", .path = "/v1/volumes"};
    sdfq_reply reply;
    int rc = sdfq_http(srv, &req, &reply);
    if (rc)
        return rc;
    cJSON *root = cJSON_ParseWithLength(reply.body ? reply.body : "", reply.len);
    cJSON *list = cJSON_GetObjectItemCaseSensitive(root, "volumes"), *v;
    if (!cJSON_IsArray(list)) {
        fprintf(stderr, "sdfq: %s/v1/volumes: not the JSON the API documents\n", srv->url);
        rc = SDFQ_CONNECT;
    }
    cJSON_ArrayForEach(v, list) {
        cJSON *dims = cJSON_GetObjectItemCaseSensitive(v, "dims");
        const char *name = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(v, "name"));
        const char *enc = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(v, "encoding"));
        printf("%s\t%dx%dx%d\torder %d\t%s\t%.0f\n", name ? name : "?",
               (int)cJSON_GetNumberValue(cJSON_GetArrayItem(dims, 0)),
               (int)cJSON_GetNumberValue(cJSON_GetArrayItem(dims, 1)),
               (int)cJSON_GetNumberValue(cJSON_GetArrayItem(dims, 2)),
               (int)cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(v, "order")),
               enc ? enc : "?",
               cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(v, "bytes")));
    }
    cJSON_Delete(root);
    sdfq_reply_free(&reply);
    return rc;
}
