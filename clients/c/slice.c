/* slice.c - `sdfq slice`: a slice picture (PNG) or its values (npy) of a mesh or a volume
 * saved to a file (docs/api.md, "Slices"). The options are the route's URL arguments, passed
 * on as given, so the server judges them and a refusal names the argument. */
#include <curl/curl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "commands.h"
#include "http.h"

/* The options sent as URL arguments of the same name (the filter's: query's few). */
static const char *const passed[] = {"axis", "at", "normal", "origin", "bounds", "size", "mode",
                                     "sign", "interpolation", "step", "samples", "seed",
                                     "kernel", "cap"};

/* Append "&name=value" (escaped) to the path being built; 0 or -1 (out of memory). */
static int append(char **path, const char *name, const char *value)
{
    char *v = curl_easy_escape(NULL, value, 0);
    size_t n = v ? strlen(*path) + strlen(name) + strlen(v) + 3 : 0;
    char *grown = n ? realloc(*path, n) : NULL;
    if (grown) {
        size_t at = strlen(grown);
        snprintf(grown + at, n - at, "%c%s=%s", strchr(grown, '?') ? '&' : '?', name, v);
        *path = grown;
    }
    curl_free(v);
    return grown ? 0 : -1;
}

int sdfq_cmd_slice(const sdfq_server *srv, const sdfq_args *a)
{
    const char *out = sdfq_opt_value(a, "o");
    if (a->npos != 1 || !out) {
        fprintf(stderr, "sdfq slice: needs a MESH (or --volume VOLUME) and -o FILE "
                        "(see sdfq slice --help)\n");
        return SDFQ_USAGE;
    }
    const char *format = sdfq_opt_value(a, "format");
    size_t len = strlen(out);
    if (!format)
        format = len > 4 && !strcmp(out + len - 4, ".npy") ? "npy" : "png";
    char *name = sdfq_escape(a->pos[0]);
    const char *kind = sdfq_opt_value(a, "volume") ? "volumes" : "meshes";
    size_t n = name ? strlen(kind) + strlen(name) + 32 : 0;
    char *path = n ? malloc(n) : NULL;
    int failed = !path;
    if (path)
        snprintf(path, n, "/v1/%s/%s/slice.png", kind, name);
    free(name);
    for (size_t i = 0; !failed && i < sizeof passed / sizeof *passed; i++) {
        const char *v = sdfq_opt_value(a, passed[i]);
        failed = v && append(&path, passed[i], v);
    }
    if (!failed && strcmp(format, "png"))
        failed = append(&path, "format", format);
    if (failed) {
        free(path);
        fprintf(stderr, "sdfq: out of memory\n");
        return SDFQ_CONNECT;
    }
    sdfq_request req = {.method = "GET", .path = path, .save_to = out};
    sdfq_reply reply;
    int rc = sdfq_http(srv, &req, &reply);
    if (!rc)
        sdfq_reply_free(&reply);
    free(path);
    return rc;
}
