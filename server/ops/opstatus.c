/* opstatus.c - liveness, readiness, metrics and the API document (opstatus.h). */
#include "ops/opstatus.h"

#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "ops/apidoc.h"

static int status(sdfd_call *call, int code, const char *state)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "status", state);
    return sdfd_call_json(call, code, o);
}

int sdfd_op_health(sdfd_call *call)
{
    return status(call, 200, "ok");
}

int sdfd_op_ready(sdfd_call *call)
{
    sdfd_server *srv = call->srv;
    if (atomic_load(&srv->draining))
        return status(call, 503, "draining");
    if (!atomic_load(&srv->ready))
        return status(call, 503, "loading");
    char why[256];
    return sdfd_cache_probe(srv->cache, why, sizeof why) ? status(call, 503, "store unreadable")
                                                         : status(call, 200, "ready");
}

int sdfd_op_metrics(sdfd_call *call)
{
    sdfd_server *srv = call->srv;
    sdfd_gauges g = {.meshes_loaded = sdfd_registry_count(srv->registry),
                     .volumes_loaded = sdfd_volumes_count(srv->volumes),
                     .buffered_bytes = atomic_load(&srv->buffered),
                     .batch_scratch_bytes = sdfd_batcher_kept_bytes(srv->batcher)};
    sdfd_volumes_usage(srv->volumes, &g.volume_bytes, &g.bakes_running, &g.bakes_queued);
    sdfd_volumes_ops_usage(srv->volumes, &g.ops_running, &g.ops_queued);
    sdfd_workers_counts(srv->workers, &g.workers_idle, &g.workers_started);
    sdfd_cache_stats st;
    sdfd_cache_stats_get(srv->cache, &st);
    g.resident_bytes = st.resident_bytes, g.resident_budget = st.budget;
    g.store_loads = st.loads, g.store_evictions = st.evictions;
    g.store_quarantined = st.quarantined, g.store_hits = st.hits;
    char *catalog = NULL;
    if (srv->cfg.catalog) {
        sdfd_catalog_job_counts jobs = {0};
        /* /metrics answers while sdfd loads; main sets srv->jobs before `ready`. */
        if (atomic_load(&srv->ready) && srv->jobs)
            sdfd_jobrunner_counts_get(srv->jobs, &jobs);
        catalog = sdfd_catalog_metrics_render(&srv->catalog_metrics, &jobs, &g.extra_len);
        g.extra = catalog;
    }
    sdfd_result *r = &call->result;
    r->bytes = sdfd_metrics_render(srv->metrics, &g, &r->len);
    free(catalog);
    if (!r->bytes)
        return sdfd_call_fail(call, SDF_ENOMEM, "out of memory");
    r->status = 200;
    r->type = "text/plain; version=0.0.4";
    return SDFD_CALL_READY;
}

int sdfd_op_openapi(sdfd_call *call)
{
    sdfd_result *r = &call->result;
    r->bytes = malloc(sdfd_openapi_json_size);
    if (!r->bytes)
        return sdfd_call_fail(call, SDF_ENOMEM, "out of memory");
    memcpy(r->bytes, sdfd_openapi_json, sdfd_openapi_json_size);
    r->len = sdfd_openapi_json_size;
    r->status = 200;
    r->type = "application/json";
    return SDFD_CALL_READY;
}
