/* main.c - sdfd: load the meshes, start the batcher and both front ends, and on SIGTERM or
 * SIGINT shut down gracefully: /readyz turns 503, no new connections are accepted, requests
 * in flight are answered (for up to --drain-seconds), then everything stops and the process
 * exits 0. SIGHUP rereads --tls-cert and --tls-key (tls.c); open connections go on.
 *
 * Signals are blocked in every thread and taken synchronously by the main thread with
 * sigwait, so no handler runs inside library code. */
#include <dirent.h>
#include <malloc.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "core/log.h"
#include "ops/opjobs.h"
#include "ops/optable.h"
#include "state/backcat.h"
#include "state/backfile.h"
#include "state/catimport.h"
#include "state/server.h"
#include "transport/binary.h"
#include "transport/http.h"
#include "transport/tls.h"

static int load_mesh(sdfd_server *srv, const char *name, const char *path)
{
    sdf_mesh_options opts = {.max_triangles = srv->cfg.max_total_triangles};
    sdf_mesh *mesh;
    sdf_diag diag;
    if (!sdfd_valid_name(name, strlen(name))) {
        sdfd_log("error", "mesh", "'%s' is not a valid mesh name (A-Z a-z 0-9 . _ -)", name);
        return -1;
    }
    /* At start the registry holds only what the flags named: one name twice (two --mesh
     * flags, or cube.obj beside cube.ply in --mesh-dir, read in directory order) would
     * leave whichever came last. */
    sdf_mesh *earlier = sdfd_registry_get(srv->registry, name, strlen(name));
    if (earlier) {
        sdf_mesh_release(earlier);
        sdfd_log("error", "mesh", "two meshes are named '%s' (the second is %s): name them apart",
                 name, path);
        return -1;
    }
    if (sdf_mesh_load_file(path, &opts, &mesh, &diag)) {
        sdfd_log("error", "mesh", "cannot load %s: %s", path, diag.message);
        return -1;
    }
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    if (sdfd_registry_put(srv->registry, name, mesh, NULL)) {
        sdfd_log("error", "mesh", "%s: over --max-meshes or --max-triangles", path);
        return -1;
    }
    sdfd_cache_pin(srv->cache, name);
    sdfd_log("info", "mesh_loaded", "%s: %s, %zu triangles, closed %d, sign %s, %.3f s", name,
             path, r.triangles, r.closed, sdf_sign_name(r.auto_sign), r.build_seconds);
    return 0;
}

static int load_dir(sdfd_server *srv, const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) {
        sdfd_log("error", "mesh", "cannot open --mesh-dir %s", dir);
        return -1;
    }
    int rc = 0;
    for (struct dirent *e; !rc && (e = readdir(d));) {
        const char *dot = strrchr(e->d_name, '.');
        sdf_format f;
        if (!dot || dot == e->d_name || sdf_format_from_name(dot + 1, &f))
            continue;
        char name[256], path[4096];
        snprintf(name, sizeof name, "%.*s", (int)(dot - e->d_name), e->d_name);
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        rc = load_mesh(srv, name, path);
    }
    closedir(d);
    return rc;
}

static int load_meshes(sdfd_server *srv)
{
    for (size_t i = 0; i < srv->cfg.mesh_count; i++)
        if (load_mesh(srv, srv->cfg.meshes[i].name, srv->cfg.meshes[i].path))
            return -1;
    if (srv->cfg.mesh_dir && load_dir(srv, srv->cfg.mesh_dir))
        return -1;
    /* The demo stands in for an empty server; a store is not one. */
    if (srv->cfg.mesh_count == 0 && !srv->cfg.mesh_dir && !srv->cfg.data_dir &&
        !srv->cfg.catalog) {
        sdf_mesh *demo;
        if (sdf_mesh_create_demo(&demo) || sdfd_registry_put(srv->registry, "demo", demo, NULL))
            return -1;
        sdfd_log("info", "mesh_loaded", "demo: built-in trefoil-knot tube, 12288 triangles");
    }
    return 0;
}

/* sdfd --catalog URI --import DIR: 0 when every item was copied (or was there already, or
 * was damaged and left out, logged), 1 otherwise. */
static int import_store(const sdfd_config *cfg)
{
    sdfd_catalog *c = NULL;
    sdfd_catimport_counts n;
    char err[512];
    int rc = sdfd_catalog_open(cfg->catalog, NULL, &c, err, sizeof err);
    if (!rc)
        rc = sdfd_catimport_run(cfg->import_dir, c, &n, err, sizeof err);
    sdfd_catalog_close(c);
    if (rc) {
        sdfd_log("error", "import", "%s", err);
        return 1;
    }
    sdfd_log("info", "import", "%s: %zu items copied, %zu already there, %zu damaged (left "
             "out)", cfg->import_dir, n.copied, n.unchanged, n.damaged);
    return 0;
}

static void drain(sdfd_server *srv)
{
    double deadline = sdfd_now() + srv->cfg.drain_seconds;
    while (atomic_load(&srv->in_flight) > 0 && sdfd_now() < deadline) {
        struct timespec ts = {0, 5000000};
        nanosleep(&ts, NULL);
    }
    long left = atomic_load(&srv->in_flight);
    if (left > 0)
        sdfd_log("warn", "shutdown", "%ld requests still in flight after %u s", left,
                 srv->cfg.drain_seconds);
}

/* SIGHUP: new handshakes use the files' new contents; connections already open keep theirs.
 * A file that does not load leaves the certificate in use as it was. */
static void reload_tls(sdfd_server *srv)
{
    char err[512];
    if (!srv->tls)
        sdfd_log("info", "tls_reload", "SIGHUP ignored: sdfd serves no TLS");
    else if (sdfd_tls_reload(srv->tls, err, sizeof err))
        sdfd_log("error", "tls_reload", "%s; the certificate in use stays", err);
    else
        sdfd_log("info", "tls_reload", "new connections use %s", srv->cfg.tls_cert);
}

/* sdfd's buffers (request bodies, replies, batches, bakes) range from bytes to hundreds of
 * MB. glibc raises its mmap threshold after each large buffer is freed (up to 32 MiB), so
 * later large buffers come from the heap, fragment it, and the resident size climbs under a
 * steady load (the soak test saw +45 % in two minutes). Fixed thresholds keep large buffers in
 * their own mappings, returned to the system when freed. */
static void fix_malloc_thresholds(void)
{
    mallopt(M_MMAP_THRESHOLD, 128 * 1024);
    mallopt(M_TRIM_THRESHOLD, 128 * 1024);
}

int main(int argc, char **argv)
{
    static sdfd_server srv;
    fix_malloc_thresholds();
    if (argc == 2 && !strcmp(argv[1], "--describe-routes")) { /* the table, for the API test */
        sdfd_op_describe(stdout);
        return 0;
    }
    int rc = sdfd_config_parse(&srv.cfg, argc, argv);
    if (rc)
        return rc > 0 ? 0 : 2;
    if (srv.cfg.import_dir)
        return import_store(&srv.cfg);
    static char host[64];
    if (!srv.cfg.replica_id) /* jobs name the replica that runs them */
        srv.cfg.replica_id = gethostname(host, sizeof host - 1) ? "sdfd" : host;
    sigset_t signals;
    sigemptyset(&signals);
    sigaddset(&signals, SIGTERM);
    sigaddset(&signals, SIGINT);
    sigaddset(&signals, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &signals, NULL); /* inherited by every thread */
    signal(SIGPIPE, SIG_IGN);

    srv.registry = sdfd_registry_create(srv.cfg.max_meshes, srv.cfg.max_total_triangles);
    const char *labels[SDFD_OP_LABELS];
    for (size_t i = 0; i < SDFD_OP_LABELS; i++)
        labels[i] = sdfd_op_label(i);
    srv.metrics = sdfd_metrics_create(labels, SDFD_OP_LABELS);
    srv.volumes = sdfd_volumes_create(srv.cfg.max_volumes, srv.cfg.max_volume_bytes,
                                      (int)srv.cfg.max_bakes, srv.cfg.max_jobs,
                                      srv.cfg.max_bake_queries, srv.cfg.threads);
    sdfd_store *store = NULL;
    char err[512];
    /* Both files are checked before anything listens: a bad one is a start-up error, not a
     * failed handshake for every client later. */
    if (srv.cfg.tls_cert && sdfd_tls_open(srv.cfg.tls_cert, srv.cfg.tls_key, &srv.tls, err,
                                          sizeof err)) {
        sdfd_log("error", "start", "%s", err);
        return 2;
    }
    if (srv.cfg.data_dir && !srv.cfg.catalog && sdfd_store_open(srv.cfg.data_dir, &store, err, sizeof err)) {
        sdfd_log("error", "start", "--data-dir: %s", err);
        return 1;
    }
    sdfd_backing backing = {0};
    if (store)
        sdfd_backfile_init(store, &backing);
    if (srv.cfg.catalog &&
        sdfd_backcat_create(srv.cfg.catalog, srv.cfg.data_dir, srv.cfg.cache_bytes,
                            &srv.catalog_metrics, &backing, err, sizeof err)) {
        sdfd_log("error", "start", "--catalog: %s", err);
        return 1;
    }
    srv.cache = sdfd_cache_create(backing.ops ? &backing : NULL, srv.registry, srv.volumes, srv.metrics,
                                  srv.cfg.max_resident_bytes, srv.cfg.max_total_triangles);
    if (!srv.registry || !srv.metrics || !srv.volumes || !srv.cache ||
        sdfd_workers_create(SDFD_IDLE_WORKERS, &srv.workers) ||
        sdfd_batcher_create(srv.cfg.threads, srv.cfg.batch_window_us, srv.cfg.batch_max_points,
                            srv.cfg.max_queued_points, srv.metrics, &srv.batcher)) {
        sdfd_log("error", "start", "out of memory");
        return 1;
    }
    sdfd_log("info", "start", "sdfd %s starting", SDFD_VERSION);
    sdfd_http *http = NULL;
    sdfd_binary *bin = NULL;
    /* Listen first (so /readyz can say "loading"), then load. */
    if (sdfd_http_start(&srv, &http) || sdfd_binary_start(&srv, &bin) || load_meshes(&srv)) {
        sdfd_cache_destroy(srv.cache);
        sdfd_binary_stop(bin);
        sdfd_http_stop(http);
        sdfd_workers_destroy(srv.workers);
        sdfd_batcher_destroy(srv.batcher);
        sdfd_volumes_destroy(srv.volumes);
        sdfd_tls_destroy(srv.tls);
        return 1;
    }
    /* the flags' meshes first: they win over the store's */
    if (sdfd_cache_start(srv.cache, err, sizeof err)) {
        sdfd_log("error", "start", "%s: %s", srv.cfg.catalog ? "--catalog" : "--data-dir", err);
        return 1;
    }
    if (srv.cfg.catalog &&
        !(srv.jobs = sdfd_jobrunner_create(sdfd_backcat_catalog(&backing), srv.cache,
                                           srv.volumes, srv.cfg.replica_id, srv.cfg.max_bakes,
                                           srv.cfg.catalog_grace_seconds, sdfd_op_start_shared,
                                           &srv))) {
        sdfd_log("error", "start", "cannot start the job runner");
        return 1;
    }
    atomic_store(&srv.ready, 1);
    sdfd_log("info", "ready", "serving %zu meshes", sdfd_registry_count(srv.registry));

    int sig;
    while (!sigwait(&signals, &sig) && sig == SIGHUP)
        reload_tls(&srv);
    sdfd_log("info", "shutdown", "%s: draining", sig == SIGTERM ? "SIGTERM" : "SIGINT");
    atomic_store(&srv.draining, 1);
    sdfd_jobrunner_stop(srv.jobs); /* before the volumes cancel what it claimed */
    sdfd_volumes_close(srv.volumes); /* bakes stop at their next slab */
    sdfd_http_quiesce(http);
    sdfd_binary_quiesce(bin);
    drain(&srv);
    /* Loads still under way (if the drain timed out) end, and the queries that waited for
     * them reach the batcher, before it stops. */
    sdfd_cache_stop_loads(srv.cache);
    /* The batcher finishes any job still queued (if the drain timed out) while both front
     * ends can still take the replies; only then do they close. */
    sdfd_batcher_destroy(srv.batcher);
    sdfd_binary_stop(bin);
    sdfd_http_stop(http);
    sdfd_workers_destroy(srv.workers); /* their tasks ended with the requests they served */
    sdfd_volumes_destroy(srv.volumes);
    sdfd_jobrunner_destroy(srv.jobs); /* after the volumes: their hooks report to it */
    sdfd_cache_destroy(srv.cache);
    sdfd_registry_destroy(srv.registry);
    sdfd_metrics_destroy(srv.metrics);
    sdfd_tls_destroy(srv.tls); /* after both front ends: their sessions have ended */
    sdfd_log("info", "stopped", "bye");
    return 0;
}
