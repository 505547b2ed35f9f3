/* mesh.c - `sdfq mesh`: a volume's surface (docs/api.md, "Meshes from volumes") saved as a
 * mesh file, or stored on the server as a mesh with --mesh NEW (whose report it prints).
 * --iso and --cap go as given, so the server judges them and a refusal names them. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "commands.h"
#include "http.h"

/* The file's format: --format, else FILE's extension (.obj, .stl, .off), else ply. */
static const char *file_format(const sdfq_args *a, const char *out)
{
    const char *format = sdfq_opt_value(a, "format");
    const char *dot = strrchr(out, '.');
    if (format)
        return format;
    if (dot && (!strcmp(dot, ".obj") || !strcmp(dot, ".stl") || !strcmp(dot, ".off")))
        return dot + 1;
    return "ply";
}

/* POST {"mesh": NEW, "iso": ..., "cap": ...} with iso as typed (a JSON number, or 422). */
static int store(const sdfq_server *srv, const char *path, const sdfq_args *a, const char *mesh)
{
    char body[1024];
    const char *iso = sdfq_opt_value(a, "iso");
    size_t n = strlen(mesh);
    if (n > 255 || strpbrk(mesh, "\"\\") || (iso && strlen(iso) > 64)) {
        fprintf(stderr, "sdfq mesh: --mesh must be a name (1-255 of A-Z a-z 0-9 . _ -) and "
                        "--iso a number\n");
        return SDFQ_USAGE;
    }
    snprintf(body, sizeof body, "{\"mesh\":\"%s\",\"iso\":%s,\"cap\":%s}", mesh, iso ? iso : "0",
             sdfq_opt_value(a, "cap") ? "true" : "false");
    sdfq_request req = {.method = "POST", .path = path, .body = body, .body_len = strlen(body),
                        .content_type = "application/json"};
    sdfq_reply reply;
    int rc = sdfq_http(srv, &req, &reply);
    if (!rc) {
        printf("%s\n", reply.body ? reply.body : "");
        sdfq_reply_free(&reply);
    }
    return rc;
}

int sdfq_cmd_mesh(const sdfq_server *srv, const sdfq_args *a)
{
    const char *out = sdfq_opt_value(a, "o"), *mesh = sdfq_opt_value(a, "mesh");
    if (a->npos != 1 || !out == !mesh) {
        fprintf(stderr, "sdfq mesh: needs a VOLUME and either -o FILE or --mesh NEW "
                        "(see sdfq mesh --help)\n");
        return SDFQ_USAGE;
    }
    char *name = sdfq_escape(a->pos[0]), *iso = NULL;
    const char *iso_text = sdfq_opt_value(a, "iso");
    if (iso_text && !(iso = sdfq_escape(iso_text)))
        name = (free(name), NULL);
    size_t n = name ? strlen(name) + (iso ? strlen(iso) : 0) + 96 : 0;
    char *path = n ? malloc(n) : NULL;
    if (!path) {
        free(name), free(iso);
        fprintf(stderr, "sdfq: out of memory\n");
        return SDFQ_CONNECT;
    }
    int rc;
    if (mesh) {
        snprintf(path, n, "/v1/volumes/%s/mesh", name);
        rc = store(srv, path, a, mesh);
    } else {
        snprintf(path, n, "/v1/volumes/%s/mesh?format=%s&cap=%s%s%s", name,
                 file_format(a, out), sdfq_opt_value(a, "cap") ? "true" : "false",
                 iso ? "&iso=" : "", iso ? iso : "");
        sdfq_request req = {.method = "GET", .path = path, .save_to = out};
        sdfq_reply reply;
        if (!(rc = sdfq_http(srv, &req, &reply)))
            sdfq_reply_free(&reply);
    }
    free(path), free(name), free(iso);
    return rc;
}
