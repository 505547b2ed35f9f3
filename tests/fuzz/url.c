/* url.c - fuzzes the parsers of sdfd's URL arguments: the input is a query string
 * ("mode=filtered&cap=0.1&smooth_sphere=0,0,0,1"), split and unescaped as libmicrohttpd does
 * ('+' is a space, %XX a byte, the first of repeated keys wins, a key without '=' has no
 * value), then read as sdfd reads it: the filter's parameters (server/filterparams.c,
 * sdfd_filter_from_strings, then the library's checks on the demo mesh) and the names of a
 * query's mode, sign and interpolation and an upload's or a download's format. A bake takes
 * no URL arguments (its body is JSON: json_bake). */
#include <ctype.h>

#include "filterparams.h"
#include "fuzz.h"
#include "proto.h"

#define MAX_ARGS 64

typedef struct args {
    char *key[MAX_ARGS], *value[MAX_ARGS];
    int n;
} args;

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

static void split(char *query, args *a)
{
    a->n = 0;
    for (char *p = query; p && a->n < MAX_ARGS;) {
        char *next = strchr(p, '&');
        if (next)
            *next++ = 0;
        char *eq = strchr(p, '=');
        if (eq)
            *eq++ = 0;
        unescape(p);
        if (eq)
            unescape(eq);
        a->key[a->n] = p, a->value[a->n] = eq;
        a->n++;
        p = next;
    }
}

static const char *lookup(void *ctx, const char *name)
{
    const args *a = ctx;
    for (int i = 0; i < a->n; i++)
        if (!strcmp(a->key[i], name))
            return a->value[i];
    return NULL;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *query = fuzz_text(data, size);
    if (!query)
        return 0;
    args a;
    split(query, &a);
    sdf_proto_mode mode;
    sdf_sign_method sign;
    sdf_volume_filter interpolation;
    sdf_format format;
    sdf_volume_file file;
    const char *v;
    if ((v = lookup(&a, "mode")))
        (void)sdf_proto_mode_from_name(v, &mode);
    if ((v = lookup(&a, "sign")))
        (void)sdf_sign_from_name(v, &sign);
    if ((v = lookup(&a, "interpolation")))
        (void)sdf_volume_filter_from_name(v, &interpolation);
    if ((v = lookup(&a, "format"))) {
        (void)sdf_format_from_name(v, &format);
        (void)sdf_volume_file_from_name(v, &file);
    }
    sdf_filter_options f;
    char volume_mesh[SDFD_VOLUME_NAME_MAX + 1], err[300];
    sdf_mesh *mesh = fuzz_demo_mesh();
    if (sdfd_filter_from_strings(lookup, &a, &f, volume_mesh, err, sizeof err)) {
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
