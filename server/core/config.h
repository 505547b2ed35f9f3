/* config.h - sdfd's settings: every flag, its SDFD_* environment variable, its default.
 * Flags win over the environment, which wins over defaults. */
#ifndef SDFD_CONFIG_H
#define SDFD_CONFIG_H

#include <stddef.h>
#include <stdint.h>

#define SDFD_MAX_MESH_ARGS 64

typedef struct sdfd_mesh_arg {
    const char *name, *path;
} sdfd_mesh_arg;

typedef struct sdfd_config {
    const char *http_addr;        /* HOST:PORT; port 0 picks a free one (logged at start) */
    const char *bin_addr;
    sdfd_mesh_arg meshes[SDFD_MAX_MESH_ARGS];
    size_t mesh_count;
    const char *mesh_dir;
    int threads;                  /* 0 = all CPUs */
    const char *token;            /* NULL = no authentication */
    int auth_queries;             /* queries need the token too */
    size_t max_body_bytes;
    size_t max_buffered_bytes;    /* request bodies and binary frames held, all connections */
    size_t max_points;            /* per request */
    unsigned max_connections;
    unsigned max_per_ip;
    unsigned timeout_seconds;     /* idle connection timeout */
    size_t max_meshes;
    size_t max_total_triangles;
    unsigned batch_window_us;     /* how long the batcher waits for more requests */
    size_t batch_max_points;      /* ... or until this many points are waiting */
    size_t max_queued_points;     /* more waiting than this: new requests get 429 */
    unsigned drain_seconds;       /* graceful shutdown: how long in-flight work may take */
    size_t max_volumes;           /* baked volumes kept */
    size_t max_volume_bytes;      /* their bytes, plus what running bakes will need */
    size_t max_bake_queries;      /* distance queries one bake may cost */
    unsigned max_bakes;           /* bakes running at once */
    size_t max_jobs;              /* bake jobs remembered */
    const char *data_dir;         /* the store, or NULL: memory only */
    const char *catalog;          /* PostgreSQL's conninfo, or NULL (data_dir: its blob cache) */
    size_t cache_bytes;           /* with catalog and data_dir: bound on the blob cache */
    const char *replica_id;       /* the owner jobs name; NULL: the host name (main.c) */
    unsigned catalog_grace_seconds; /* blobs unreferenced this long are swept */
    const char *import_dir;       /* --import: copy this file store into the catalog, exit */
    size_t max_resident_bytes;    /* with a store: meshes and volumes kept in memory; 0 = all */
    const char *tls_cert;         /* PEM certificate (chain): HTTPS on http_addr; NULL = HTTP */
    const char *tls_key;          /* its PEM private key; given with tls_cert or not at all */
    int bin_tls;                  /* the binary protocol over TLS too, same certificate */
} sdfd_config;

/* Fill `cfg` from argv and the environment. Returns 0; 1 if --help or --version was printed
 * (exit 0); -1 after printing a clear message to stderr (exit non-zero). */
int sdfd_config_parse(sdfd_config *cfg, int argc, char **argv);

/* The largest binary payload the server reads: a QUERY of --max-points points, with room for
 * its prefix, name and FILTER block (binary.c's max_payload, announced in HELLO_OK). */
size_t sdfd_max_payload(const sdfd_config *cfg);

/* Is `given` (n bytes) the --token (1 when there is none)? In a time that depends on the
 * token's length only, never on where the first difference lies, which a client could
 * otherwise time byte by byte. */
int sdfd_token_matches(const sdfd_config *cfg, const char *given, size_t n);

/* Split "HOST:PORT" ("[::1]:8080" for IPv6) into host and port; 0 or -1. */
int sdfd_split_address(const char *addr, char *host, size_t host_cap, char *port, size_t port_cap);

#endif
