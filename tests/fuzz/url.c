/* url.c - fuzzes the parsers of sdfd's URL arguments: the input is a query string
 * ("mode=filtered&cap=0.1&smooth_sphere=0,0,0,1"), split and unescaped as libmicrohttpd does
 * ('+' is a space, %XX a byte, repeated keys all kept, a key without '=' has no value), then
 * read as sdfd reads it: the check of every route's table (server/ops/urlargs.c), a slice's
 * parameters of both kinds (server/ops/slice.c), the filter's parameters (server/ops/filterparams.c,
 * sdfd_filter_from_strings, then the library's checks on the demo mesh) and the names of a
 * query's mode, sign and interpolation and an upload's or a download's format. A bake takes
 * no URL arguments (its body is JSON: json_bake). */
#include <ctype.h>

#include "ops/filterparams.h"
#include "fuzz.h"
#include "proto.h"
#include "ops/slice.h"
#include "ops/urlargs.h"

static int hex(int c) { return isdigit(c) ? c - '0' : tolower(c) - 'a' + 10; }

/* Unescape in place: '+' -> ' ', %XX -> the byte (a bad escape stays as it is). */
static void unescape(char *s)
{
    char *w = s;
    for (char *r = s; *r; r++) {
        if (*r == '+') {
            *w++ = ' ';
        } else if (r[0] == '%' && isxdigit((unsigned char)r[1]) && isxdigit((unsigned char)r[2])) {
            *w++ = (char)(hex((unsigned char)r[1]) * 16 + hex((unsigned char)r[2]));
            r += 2;
        } else {
            *w++ = *r;
        }
    }
    *w = 0;
}

static void split(char *query, sdfd_url_args *a)
{
    *a = (sdfd_url_args){.n = 0};
    for (char *p = query; p;) {
        char *next = strchr(p, '&');
        if (next)
            *next++ = 0;
        char *eq = strchr(p, '=');
        if (eq)
            *eq++ = 0;
        unescape(p);
        if (eq)
            unescape(eq);
        sdfd_url_args_add(a, p, eq);
        p = next;
    }
}

/* Whether `name` is one of the arguments' names. */
static int holds(const sdfd_url_args *a, const char *name)
{
    for (size_t i = 0; i < a->n; i++)
        if (!strcmp(a->arg[i].name, name))
            return 1;
    return 0;
}

/* Every operation sdfd answers, checked against its line of the table (optable.c): a
 * refusal has a message and names an argument the query string holds (or "" when the count
 * is to blame). */
static void check_routes(const sdfd_url_args *a)
{
    for (int op = 0; op < SDFD_OP_COUNT; op++) {
        char err[300];
        const char *argument = NULL;
        if (!sdfd_url_args_check(a, sdfd_op_get((sdfd_op_id)op), err, sizeof err, &argument)) {
            FUZZ_CHECK(argument && !argument[0]);
            continue;
        }
        FUZZ_CHECK(err[0] && memchr(err, 0, sizeof err) && argument);
        FUZZ_CHECK(holds(a, argument) || (!argument[0] && a->given > SDFD_URL_MAX_ARGS));
    }
}

static void parse_slices(const sdfd_url_args *a)
{
    for (int volume = 0; volume < 2; volume++) {
        sdfd_slice_params params;
        char err[300];
        const char *argument = NULL;
        if (sdfd_slice_parse(a, volume, &params, err, sizeof err, &argument))
            FUZZ_CHECK(err[0] && memchr(err, 0, sizeof err) && argument &&
                       (holds(a, argument) || !argument[0]));
        else
            FUZZ_CHECK(params.size >= 1 && params.size <= SDFD_SLICE_MAX_SIZE);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *query = fuzz_text(data, size);
    if (!query)
        return 0;
    sdfd_url_args a;
    split(query, &a);
    check_routes(&a);
    parse_slices(&a);
    sdf_proto_mode mode;
    sdf_sign_method sign;
    sdf_volume_filter interpolation;
    sdf_format format;
    sdf_volume_file file;
    const char *v;
    if ((v = sdfd_url_value(&a, "mode")))
        (void)sdf_proto_mode_from_name(v, &mode);
    if ((v = sdfd_url_value(&a, "sign")))
        (void)sdf_sign_from_name(v, &sign);
    if ((v = sdfd_url_value(&a, "interpolation")))
        (void)sdf_volume_filter_from_name(v, &interpolation);
    if ((v = sdfd_url_value(&a, "format"))) {
        (void)sdf_format_from_name(v, &format);
        (void)sdf_volume_file_from_name(v, &file);
    }
    sdf_filter_options f;
    char volume_mesh[SDFD_VOLUME_NAME_MAX + 1], err[300];
    sdf_mesh *mesh = fuzz_demo_mesh();
    if (sdfd_filter_from_strings(sdfd_url_lookup, &a, &f, volume_mesh, err, sizeof err)) {
        FUZZ_CHECK(memchr(err, 0, sizeof err));
    } else if (mesh) {
        FUZZ_CHECK(memchr(volume_mesh, 0, sizeof volume_mesh));
        if (volume_mesh[0])
            f.smooth.mesh = mesh;
        sdf_query_result none = {0};
        sdf_diag diag = {0};
        if (sdf_query_filtered(mesh, NULL, 0, NULL, &f, &none, &diag))
            FUZZ_CHECK(diag.message[0] && memchr(diag.message, 0, sizeof diag.message));
    }
    free(query);
    return 0;
}
