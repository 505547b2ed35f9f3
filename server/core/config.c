/* config.c - flags and SDFD_* environment variables (see config.h). One table drives both
 * the parsing and --help, so a setting cannot be documented without existing or vice versa. */
#include "core/config.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h" /* SDF_PROTO_HEADER_SIZE */

enum kind { STRING, SIZE, UINT, INT, BOOL, MESH };

typedef struct setting {
    const char *flag, *env, *meta, *help;
    enum kind kind;
    size_t offset;
    unsigned long long min, max; /* numbers: the values accepted */
} setting;

#define AT(field) offsetof(sdfd_config, field)

static const setting settings[] = {
    {"--http", "SDFD_HTTP", "HOST:PORT", "HTTP address (default 127.0.0.1:8080)", STRING, AT(http_addr), 0, 0},
    {"--bin", "SDFD_BIN", "HOST:PORT", "binary protocol address (default 127.0.0.1:9090)", STRING, AT(bin_addr), 0, 0},
    {"--mesh", "SDFD_MESH", "NAME=PATH", "load a mesh (repeatable; the variable takes NAME=PATH,...)", MESH, 0, 0, 0},
    {"--mesh-dir", "SDFD_MESH_DIR", "DIR", "load every .obj/.ply/.stl/.off in DIR, named by file stem", STRING, AT(mesh_dir), 0, 0},
    {"--threads", "SDFD_THREADS", "N", "geometry worker threads (default 0 = all CPUs)", INT, AT(threads), 0, 256},
    {"--token", "SDFD_TOKEN", "T", "require 'Authorization: Bearer T' for PUT, DELETE and bakes", STRING, AT(token), 0, 0},
    {"--auth-queries", "SDFD_AUTH_QUERIES", "", "require the token for queries and volume downloads too", BOOL, AT(auth_queries), 0, 1},
    {"--max-body-bytes", "SDFD_MAX_BODY_BYTES", "N", "largest request body (default 268435456)", SIZE, AT(max_body_bytes), 1, 1ull << 34},
    {"--max-buffered-bytes", "SDFD_MAX_BUFFERED_BYTES", "N", "bytes of requests held at once, all connections; past it 429 (default 2147483648)", SIZE, AT(max_buffered_bytes), 1, 1ull << 40},
    {"--max-points", "SDFD_MAX_POINTS", "N", "most points in one request (default 4194304)", SIZE, AT(max_points), 1, 1u << 30},
    {"--max-connections", "SDFD_MAX_CONNECTIONS", "N", "open connections per listener (default 512)", UINT, AT(max_connections), 1, 65536},
    {"--max-per-ip", "SDFD_MAX_PER_IP", "N", "open connections per client address (default 256)", UINT, AT(max_per_ip), 1, 65536},
    {"--timeout", "SDFD_TIMEOUT", "SECONDS", "close connections idle this long (default 30)", UINT, AT(timeout_seconds), 1, 86400},
    {"--max-meshes", "SDFD_MAX_MESHES", "N", "most meshes loaded at once (default 64)", SIZE, AT(max_meshes), 1, 1u << 20},
    {"--max-triangles", "SDFD_MAX_TRIANGLES", "N", "most triangles over all meshes (default 50000000)", SIZE, AT(max_total_triangles), 0, 1ull << 32},
    {"--batch-window-us", "SDFD_BATCH_WINDOW_US", "US", "wait this long to coalesce requests (default 200)", UINT, AT(batch_window_us), 0, 1000000},
    {"--batch-max-points", "SDFD_BATCH_MAX_POINTS", "N", "... or until this many points wait (default 262144)", SIZE, AT(batch_max_points), 0, 1u << 30},
    {"--max-queued-points", "SDFD_MAX_QUEUED_POINTS", "N", "refuse new queries (429) while this many points wait (default 16777216)", SIZE, AT(max_queued_points), 1, 1ull << 34},
    {"--max-volumes", "SDFD_MAX_VOLUMES", "N", "most baked volumes kept at once (default 64)", SIZE, AT(max_volumes), 1, 1u << 20},
    {"--max-volume-bytes", "SDFD_MAX_VOLUME_BYTES", "N", "bytes of all baked volumes and bakes in progress (default 4294967296)", SIZE, AT(max_volume_bytes), 0, 1ull << 40},
    {"--max-bake-queries", "SDFD_MAX_BAKE_QUERIES", "N", "distance queries one bake may cost (default 1073741824)", SIZE, AT(max_bake_queries), 0, 1ull << 40},
    {"--max-bakes", "SDFD_MAX_BAKES", "N", "bake and ops jobs running at once; more wait queued (default 1)", UINT, AT(max_bakes), 1, 64},
    {"--max-jobs", "SDFD_MAX_JOBS", "N", "bake jobs remembered, finished or not (default 64)", SIZE, AT(max_jobs), 1, 1u << 16},
    {"--data-dir", "SDFD_DATA_DIR", "DIR", "keep meshes, volumes and bake jobs in DIR (one sdfd per DIR; docs/api.md); with --catalog, local copies of the catalog's bytes", STRING, AT(data_dir), 0, 0},
    {"--catalog", "SDFD_CATALOG", "URI", "keep meshes, volumes and jobs in PostgreSQL (a libpq URI or key=value string; replicas share it; docs/deploy.md)", STRING, AT(catalog), 0, 0},
    {"--import", "SDFD_IMPORT", "DIR", "with --catalog: copy the file store DIR (a --data-dir) into the catalog, then exit", STRING, AT(import_dir), 0, 0},
    {"--catalog-grace", "SDFD_CATALOG_GRACE", "SECONDS", "with --catalog: delete stored bytes no item has referred to for this long (default 600)", UINT, AT(catalog_grace_seconds), 1, 864000},
    {"--cache-bytes", "SDFD_CACHE_BYTES", "N", "with --catalog and --data-dir: bytes of local copies kept, least recently used dropped first (default 8589934592; 0 = no bound)", SIZE, AT(cache_bytes), 0, 1ull << 50},
    {"--replica-id", "SDFD_REPLICA_ID", "ID", "this replica's name in the jobs it runs (default: the host name)", STRING, AT(replica_id), 0, 0},
    {"--max-resident-bytes", "SDFD_MAX_RESIDENT_BYTES", "N", "with --data-dir or --catalog: drop the least recently used meshes and volumes from memory past N bytes (default 0 = keep all)", SIZE, AT(max_resident_bytes), 0, 1ull << 44},
    {"--tls-cert", "SDFD_TLS_CERT", "FILE", "serve HTTPS (TLS 1.2+) with this PEM certificate chain; reread on SIGHUP", STRING, AT(tls_cert), 0, 0},
    {"--tls-key", "SDFD_TLS_KEY", "FILE", "the certificate's PEM private key (with --tls-cert)", STRING, AT(tls_key), 0, 0},
    {"--bin-tls", "SDFD_BIN_TLS", "", "the binary protocol over TLS too, with the same certificate", BOOL, AT(bin_tls), 0, 1},
    {"--drain-seconds", "SDFD_DRAIN_SECONDS", "SECONDS", "on SIGTERM, let in-flight requests finish this long (default 30)", UINT, AT(drain_seconds), 0, 3600},
};

#define N_SETTINGS (sizeof settings / sizeof settings[0])

static void usage(FILE *out)
{
    fprintf(out, "usage: sdfd [options]\n\n"
                 "Serves signed distance queries on triangle meshes over HTTP and a binary protocol.\n"
                 "With no --mesh or --mesh-dir it serves a built-in demo mesh named 'demo'.\n\n");
    for (size_t i = 0; i < N_SETTINGS; i++) {
        const setting *s = &settings[i];
        char left[64];
        snprintf(left, sizeof left, "%s %s", s->flag, s->meta);
        fprintf(out, "  %-28s %s\n  %-28s   [env %s]\n", left, s->help, "", s->env);
    }
    fprintf(out, "  %-28s %s\n", "--help", "show this help");
    fprintf(out, "  %-28s %s\n", "--version", "print the version and exit");
}

static int add_mesh(sdfd_config *cfg, const char *spec, const char *origin)
{
    const char *eq = strchr(spec, '=');
    if (!eq || eq == spec || !eq[1]) {
        fprintf(stderr, "sdfd: %s: expected NAME=PATH, got '%s'\n", origin, spec);
        return -1;
    }
    if (cfg->mesh_count == SDFD_MAX_MESH_ARGS) {
        fprintf(stderr, "sdfd: %s: more than %d meshes on the command line\n", origin,
                SDFD_MAX_MESH_ARGS);
        return -1;
    }
    size_t n = (size_t)(eq - spec);
    char *name = malloc(n + 1); /* lives as long as the process */
    if (!name)
        return -1;
    memcpy(name, spec, n);
    name[n] = '\0';
    cfg->meshes[cfg->mesh_count++] = (sdfd_mesh_arg){name, eq + 1};
    return 0;
}

static int set_value(sdfd_config *cfg, const setting *s, const char *value, const char *origin)
{
    char *base = (char *)cfg + s->offset;
    if (s->kind == STRING) {
        /* An empty value is a mistake, and a dangerous one for the token (SDFD_TOKEN= from
         * an unset variable would guard everything with a password anyone can send). */
        if (!value || !*value) {
            fprintf(stderr, "sdfd: %s: the value is empty\n", origin);
            return -1;
        }
        *(const char **)base = value;
        return 0;
    }
    if (s->kind == MESH) {
        /* From the environment, a comma-separated list. */
        if (strcmp(origin, s->flag) == 0)
            return add_mesh(cfg, value, origin);
        char *copy = strdup(value), *save = NULL;
        for (char *item = strtok_r(copy, ",", &save); item; item = strtok_r(NULL, ",", &save))
            if (add_mesh(cfg, item, origin))
                return -1;
        return 0;
    }
    if (s->kind == BOOL && (!value || !strcmp(value, "1") || !strcmp(value, "true"))) {
        *(int *)base = 1;
        return 0;
    }
    if (s->kind == BOOL && (!strcmp(value, "0") || !strcmp(value, "false"))) {
        *(int *)base = 0;
        return 0;
    }
    char *end;
    errno = 0;
    unsigned long long v = strtoull(value ? value : "", &end, 10);
    if (s->kind == BOOL) {
        fprintf(stderr, "sdfd: %s: '%s' is not true/false/1/0\n", origin, value ? value : "");
        return -1;
    }
    if (!value || !*value || *end || errno || value[0] == '-' || v < s->min || v > s->max) {
        fprintf(stderr, "sdfd: %s: '%s' is not a whole number in %llu..%llu\n", origin,
                value ? value : "", s->min, s->max);
        return -1;
    }
    if (s->kind == SIZE)
        *(size_t *)base = (size_t)v;
    else if (s->kind == UINT)
        *(unsigned *)base = (unsigned)v;
    else
        *(int *)base = (int)v;
    return 0;
}

static void defaults(sdfd_config *cfg)
{
    *cfg = (sdfd_config){
        .http_addr = "127.0.0.1:8080",
        .bin_addr = "127.0.0.1:9090",
        .max_body_bytes = 256u << 20,
        .max_buffered_bytes = 2ull << 30,
        .max_points = 4u << 20,
        .max_connections = 512,
        .max_per_ip = 256,
        .timeout_seconds = 30,
        .max_meshes = 64,
        .catalog_grace_seconds = 600,
        .cache_bytes = (size_t)8 << 30,
        .max_total_triangles = 50000000,
        .batch_window_us = 200,
        .batch_max_points = 262144,
        .max_queued_points = 16u << 20,
        .drain_seconds = 30,
        .max_volumes = 64,
        .max_volume_bytes = 4ull << 30,
        .max_bake_queries = 1ull << 30,
        .max_bakes = 1,
        .max_jobs = 64,
    };
}

int sdfd_config_parse(sdfd_config *cfg, int argc, char **argv)
{
    defaults(cfg);
    for (size_t i = 0; i < N_SETTINGS; i++) {
        const char *v = getenv(settings[i].env);
        if (v && set_value(cfg, &settings[i], v, settings[i].env))
            return -1;
    }
    for (int a = 1; a < argc; a++) {
        if (!strcmp(argv[a], "--help") || !strcmp(argv[a], "-h")) {
            usage(stdout);
            return 1;
        }
        if (!strcmp(argv[a], "--version")) {
            printf("sdfd %s\n", SDFD_VERSION);
            return 1;
        }
        const setting *s = NULL;
        const char *arg = argv[a], *value = NULL, *eq = strchr(arg, '=');
        size_t flag_len = eq && strncmp(arg, "--mesh=", 7) ? (size_t)(eq - arg) : strlen(arg);
        if (!strncmp(arg, "--mesh=", 7))
            flag_len = 6, value = arg + 7;
        else if (eq)
            value = eq + 1;
        for (size_t i = 0; i < N_SETTINGS; i++)
            if (strlen(settings[i].flag) == flag_len && !strncmp(arg, settings[i].flag, flag_len))
                s = &settings[i];
        if (!s) {
            fprintf(stderr, "sdfd: unknown option '%s' (see --help)\n", arg);
            return -1;
        }
        if (!value && s->kind != BOOL) {
            if (a + 1 >= argc) {
                fprintf(stderr, "sdfd: %s needs a value (%s)\n", s->flag, s->meta);
                return -1;
            }
            value = argv[++a];
        }
        if (set_value(cfg, s, value, s->flag))
            return -1;
    }
    if (!cfg->tls_cert != !cfg->tls_key) {
        fprintf(stderr, "sdfd: --tls-cert and --tls-key go together: give both or neither\n");
        return -1;
    }
    if (cfg->import_dir && !cfg->catalog) {
        fprintf(stderr, "sdfd: --import copies a file store into the catalog: it needs "
                "--catalog\n");
        return -1;
    }
    if (cfg->bin_tls && !cfg->tls_cert) {
        fprintf(stderr, "sdfd: --bin-tls needs --tls-cert and --tls-key\n");
        return -1;
    }
    /* The budget must hold the largest request it admits, or that request would be told to
     * retry for ever: a whole body, or a binary frame of --max-points points. */
    size_t frame = SDF_PROTO_HEADER_SIZE + sdfd_max_payload(cfg);
    size_t largest = cfg->max_body_bytes + 1 > frame ? cfg->max_body_bytes + 1 : frame;
    if (cfg->max_buffered_bytes < largest) {
        fprintf(stderr, "sdfd: --max-buffered-bytes %zu cannot hold the largest request, %zu "
                "bytes (--max-body-bytes + 1, or a binary frame of --max-points points)\n",
                cfg->max_buffered_bytes, largest);
        return -1;
    }
    return 0;
}

size_t sdfd_max_payload(const sdfd_config *cfg)
{
    uint64_t payload = 12ull * cfg->max_points + 4096; /* a QUERY of max_points, and room */
    return payload > UINT32_MAX ? UINT32_MAX : (size_t)payload;
}

int sdfd_token_matches(const sdfd_config *cfg, const char *given, size_t n)
{
    if (!cfg->token)
        return 1;
    size_t len = strlen(cfg->token);
    unsigned char diff = n != len;
    for (size_t i = 0; i < len; i++)
        diff |= (unsigned char)((i < n ? given[i] : 0) ^ cfg->token[i]);
    return diff == 0;
}

int sdfd_split_address(const char *addr, char *host, size_t host_cap, char *port, size_t port_cap)
{
    const char *colon = strrchr(addr, ':');
    if (!colon || !colon[1])
        return -1;
    const char *h = addr;
    size_t hn = (size_t)(colon - addr);
    if (hn >= 2 && h[0] == '[' && h[hn - 1] == ']')
        h++, hn -= 2;
    if (hn == 0 || hn >= host_cap || strlen(colon + 1) >= port_cap)
        return -1;
    memcpy(host, h, hn);
    host[hn] = '\0';
    strcpy(port, colon + 1);
    unsigned long value = 0;
    for (const char *p = port; *p; p++) {
        if (*p < '0' || *p > '9')
            return -1;
        value = value * 10 + (unsigned long)(*p - '0');
        if (value > 65535) /* getaddrinfo would wrap it to another port */
            return -1;
    }
    return 0;
}
