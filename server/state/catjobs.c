/* catjobs.c - the sdfd_jobs rows (catjobs.h; table: catschema.c, version 2). Each call is
 * one transaction through sdfd_catalog_transact; the statements that change a running row
 * all carry "owner = $ AND attempts = $ AND state = 'running'", the claim that row belongs
 * to. */
#include "state/catjobs.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "state/catconn.h"

/* What every status read selects, in parse_status's order. */
#define STATUS_COLS                                                                        \
    "id, kind, state, progress, mesh, source, volume, has_ops, caveats, warning,"          \
    " extract(epoch from coalesce(ended, now()) - created), error, message,"               \
    " cancel_requested, coalesce(owner, ''), attempts"
#define STATUS_NCOLS 16

static const char INSERT[] =
    "INSERT INTO sdfd_jobs (id, kind, state, target, request, mesh, source, volume, has_ops,"
    " created) VALUES ($1, $2, 'queued', $3, $4, $5, $6, $7, $8::boolean, clock_timestamp())";
static const char UNFINISHED[] =
    "SELECT count(*) FROM sdfd_jobs WHERE state IN ('queued', 'running')";
static const char PRUNE[] =
    "DELETE FROM sdfd_jobs WHERE id IN (SELECT id FROM sdfd_jobs WHERE state IN"
    " ('done', 'failed', 'canceled') ORDER BY created DESC OFFSET $1::bigint)";
static const char GET[] = "SELECT " STATUS_COLS " FROM sdfd_jobs WHERE id = $1";
static const char LIST[] =
    "SELECT " STATUS_COLS " FROM sdfd_jobs ORDER BY created DESC, id DESC LIMIT $1::bigint";
static const char CLAIM[] =
    "UPDATE sdfd_jobs SET state = 'running', owner = $1, attempts = attempts + 1,"
    " progress = 0, lease_until = now() + make_interval(secs => $2::float8)"
    " WHERE id = (SELECT id FROM sdfd_jobs WHERE state = 'queued' ORDER BY created"
    " LIMIT 1 FOR UPDATE SKIP LOCKED)"
    " RETURNING " STATUS_COLS ", target, encode(request, 'hex')";
static const char RENEW[] =
    "UPDATE sdfd_jobs SET progress = $4::float8,"
    " lease_until = now() + make_interval(secs => $5::float8)"
    " WHERE id = $1 AND owner = $2 AND attempts = $3::integer AND state = 'running'"
    " RETURNING cancel_requested";
static const char END[] =
    "UPDATE sdfd_jobs SET state = $4, progress = $5::float8, error = $6::integer,"
    " message = $7, caveats = $8::integer, warning = $9, ended = clock_timestamp(),"
    " lease_until = NULL"
    " WHERE id = $1 AND owner = $2 AND attempts = $3::integer AND state = 'running'";
static const char LOCK_ONE[] = "SELECT state FROM sdfd_jobs WHERE id = $1 FOR UPDATE";
static const char CANCEL_QUEUED[] =
    "UPDATE sdfd_jobs SET state = 'canceled', ended = clock_timestamp() WHERE id = $1";
static const char CANCEL_RUNNING[] =
    "UPDATE sdfd_jobs SET cancel_requested = true WHERE id = $1";
static const char FORGET[] = "DELETE FROM sdfd_jobs WHERE id = $1";
static const char EXPIRE[] =
    "UPDATE sdfd_jobs SET"
    " state = CASE WHEN cancel_requested THEN 'canceled'"
    "  WHEN attempts >= 2 THEN 'failed' ELSE 'queued' END,"
    " error = CASE WHEN NOT cancel_requested AND attempts >= 2 THEN $1::integer ELSE 0 END,"
    " message = CASE WHEN NOT cancel_requested AND attempts >= 2 THEN $2 ELSE '' END,"
    " ended = CASE WHEN cancel_requested OR attempts >= 2 THEN clock_timestamp() END,"
    " lease_until = NULL, progress = 0"
    " WHERE state = 'running' AND lease_until < now() RETURNING state";

static void copy_field(char *dst, size_t cap, const PGresult *r, int row, int col)
{
    snprintf(dst, cap, "%s", PQgetvalue(r, row, col));
}

/* Columns col .. col + STATUS_NCOLS - 1 of `row` into *s. */
static void parse_status(const PGresult *r, int row, sdfd_job_status *s)
{
    memset(s, 0, sizeof *s);
    copy_field(s->id, sizeof s->id, r, row, 0);
    if (sdfd_job_kind_from_name(PQgetvalue(r, row, 1), &s->kind))
        s->kind = SDFD_JOB_BAKE;
    static const char *const states[] = {"queued", "running", "done", "failed", "canceled"};
    for (int i = 0; i < 5; i++)
        if (!strcmp(PQgetvalue(r, row, 2), states[i]))
            s->state = (sdfd_job_state)i;
    s->progress = atof(PQgetvalue(r, row, 3));
    copy_field(s->mesh, sizeof s->mesh, r, row, 4);
    copy_field(s->source, sizeof s->source, r, row, 5);
    copy_field(s->volume, sizeof s->volume, r, row, 6);
    s->has_ops = PQgetvalue(r, row, 7)[0] == 't';
    s->caveats = (unsigned)strtoul(PQgetvalue(r, row, 8), NULL, 10);
    copy_field(s->warning, sizeof s->warning, r, row, 9);
    s->seconds = atof(PQgetvalue(r, row, 10));
    s->error = atoi(PQgetvalue(r, row, 11));
    copy_field(s->message, sizeof s->message, r, row, 12);
    s->cancel_requested = PQgetvalue(r, row, 13)[0] == 't' && s->state <= SDFD_JOB_RUNNING;
    copy_field(s->owner, sizeof s->owner, r, row, 14);
    s->attempts = atoi(PQgetvalue(r, row, 15));
}

static int exec(PGconn *conn, sdfd_catalog_metrics *m, const char *sql, int n,
                const char *const *values, PGresult **res, char *err, size_t cap)
{
    return sdfd_catconn_exec(m, conn, sql, n, values, NULL, NULL, 0, res, err, cap);
}

/* ---- insert ----------------------------------------------------------------------------- */

typedef struct insert_args {
    const sdfd_job_status *s;
    const char *target;
    const void *request;
    size_t len, max_jobs;
} insert_args;

static int insert_call(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err,
                       size_t cap)
{
    insert_args *a = arg;
    PGresult *r = NULL;
    int rc = exec(conn, m, UNFINISHED, 0, NULL, &r, err, cap);
    long long unfinished = rc ? 0 : atoll(PQgetvalue(r, 0, 0));
    PQclear(r);
    if (!rc && (size_t)unfinished >= a->max_jobs) {
        snprintf(err, cap, "%lld jobs are unfinished; retry later", unfinished);
        return SDFD_EBUSY;
    }
    const sdfd_job_status *s = a->s;
    const char *values[] = {s->id, sdfd_job_kind_name(s->kind), a->target, a->request,
                            s->mesh, s->source, s->volume, s->has_ops ? "true" : "false"};
    const int lengths[] = {0, 0, 0, (int)a->len, 0, 0, 0, 0};
    const int formats[] = {0, 0, 0, 1, 0, 0, 0, 0};
    if (!rc)
        rc = sdfd_catconn_exec(m, conn, INSERT, 8, values, lengths, formats, 0, NULL, err, cap);
    char keep[32];
    snprintf(keep, sizeof keep, "%zu", a->max_jobs);
    const char *prune[] = {keep};
    return rc ? rc : exec(conn, m, PRUNE, 1, prune, NULL, err, cap);
}

int sdfd_catjobs_insert(sdfd_catalog *c, const sdfd_job_status *s, const char *target,
                        const void *request, size_t len, size_t max_jobs, char *err, size_t cap)
{
    if (len > (1u << 30)) {
        snprintf(err, cap, "a job request of %zu bytes", len);
        return SDF_ELIMIT;
    }
    insert_args a = {s, target, request, len, max_jobs};
    return sdfd_catalog_transact(c, 1, insert_call, &a, err, cap);
}

/* ---- reads ------------------------------------------------------------------------------ */

typedef struct read_args {
    const char *id;
    size_t limit;
    sdfd_job_status *one, *list;
    size_t n;
} read_args;

static int get_call(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err, size_t cap)
{
    read_args *a = arg;
    PGresult *r = NULL;
    const char *values[] = {a->id};
    int rc = exec(conn, m, GET, 1, values, &r, err, cap);
    if (!rc && PQntuples(r) == 1)
        parse_status(r, 0, a->one);
    else if (!rc)
        rc = SDF_ENOTFOUND, snprintf(err, cap, "no job '%s'", a->id);
    PQclear(r);
    return rc;
}

int sdfd_catjobs_get(sdfd_catalog *c, const char *id, sdfd_job_status *out, char *err,
                     size_t cap)
{
    read_args a = {.id = id, .one = out};
    return sdfd_catalog_transact(c, 0, get_call, &a, err, cap);
}

static int list_call(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err, size_t cap)
{
    read_args *a = arg;
    PGresult *r = NULL;
    char limit[32];
    snprintf(limit, sizeof limit, "%zu", a->limit);
    const char *values[] = {limit};
    free(a->list); /* from an attempt that failed later */
    a->list = NULL, a->n = 0;
    int rc = exec(conn, m, LIST, 1, values, &r, err, cap);
    size_t rows = rc ? 0 : (size_t)PQntuples(r);
    if (!rc && !(a->list = calloc(rows ? rows : 1, sizeof *a->list)))
        rc = SDF_ENOMEM, snprintf(err, cap, "out of memory listing %zu jobs", rows);
    for (size_t i = 0; !rc && i < rows; i++)
        parse_status(r, (int)i, &a->list[a->n++]);
    PQclear(r);
    return rc;
}

int sdfd_catjobs_list(sdfd_catalog *c, size_t limit, sdfd_job_status **out, size_t *n,
                      char *err, size_t cap)
{
    read_args a = {.limit = limit};
    int rc = sdfd_catalog_transact(c, 0, list_call, &a, err, cap);
    if (rc) {
        free(a.list);
        a.list = NULL, a.n = 0;
    }
    *out = a.list, *n = a.n;
    return rc;
}

/* ---- claims ----------------------------------------------------------------------------- */

typedef struct claim_args {
    const char *owner;
    double lease;
    sdfd_catjob *job;
} claim_args;

static int hex_value(char c)
{
    return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
}

/* The request from its hex text into job->request. */
static int take_request(sdfd_catjob *job, const char *hex, char *err, size_t cap)
{
    size_t n = strlen(hex) / 2;
    free(job->request);
    if (!(job->request = malloc(n + 1))) {
        snprintf(err, cap, "out of memory reading a job's request");
        return SDF_ENOMEM;
    }
    for (size_t i = 0; i < n; i++) {
        int hi = hex_value(hex[2 * i]), lo = hex_value(hex[2 * i + 1]);
        if (hi < 0 || lo < 0) {
            snprintf(err, cap, "a job's request is not hex");
            return SDF_EIO;
        }
        job->request[i] = (char)(hi * 16 + lo);
    }
    job->request[n] = '\0';
    job->request_len = n;
    return 0;
}

static int claim_call(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err, size_t cap)
{
    claim_args *a = arg;
    char lease[32];
    snprintf(lease, sizeof lease, "%.3f", a->lease);
    const char *values[] = {a->owner, lease};
    PGresult *r = NULL;
    int rc = exec(conn, m, CLAIM, 2, values, &r, err, cap);
    if (!rc && PQntuples(r) == 1) {
        parse_status(r, 0, &a->job->status);
        copy_field(a->job->target, sizeof a->job->target, r, 0, STATUS_NCOLS);
        rc = take_request(a->job, PQgetvalue(r, 0, STATUS_NCOLS + 1), err, cap);
    } else if (!rc) {
        rc = SDF_ENOTFOUND, snprintf(err, cap, "no job is queued");
    }
    PQclear(r);
    return rc;
}

int sdfd_catjobs_claim(sdfd_catalog *c, const char *owner, double lease_seconds,
                       sdfd_catjob *out, char *err, size_t cap)
{
    memset(out, 0, sizeof *out);
    claim_args a = {owner, lease_seconds, out};
    int rc = sdfd_catalog_transact(c, 1, claim_call, &a, err, cap);
    if (rc) {
        free(out->request);
        out->request = NULL;
    }
    return rc;
}

typedef struct renew_args {
    const sdfd_job_status *s;
    double lease;
    int cancel;
} renew_args;

static int renew_call(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err, size_t cap)
{
    renew_args *a = arg;
    char attempts[16], progress[32], lease[32];
    snprintf(attempts, sizeof attempts, "%d", a->s->attempts);
    snprintf(progress, sizeof progress, "%.6f", a->s->progress);
    snprintf(lease, sizeof lease, "%.3f", a->lease);
    const char *values[] = {a->s->id, a->s->owner, attempts, progress, lease};
    PGresult *r = NULL;
    int rc = exec(conn, m, RENEW, 5, values, &r, err, cap);
    if (!rc && PQntuples(r) == 1)
        a->cancel = PQgetvalue(r, 0, 0)[0] == 't';
    else if (!rc)
        rc = SDF_ENOTFOUND, snprintf(err, cap, "job %s is no longer this replica's", a->s->id);
    PQclear(r);
    return rc;
}

int sdfd_catjobs_renew(sdfd_catalog *c, const sdfd_job_status *s, double lease_seconds,
                       int *cancel, char *err, size_t cap)
{
    renew_args a = {s, lease_seconds, 0};
    int rc = sdfd_catalog_transact(c, 1, renew_call, &a, err, cap);
    *cancel = a.cancel;
    return rc;
}

static int end_call(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err, size_t cap)
{
    const sdfd_job_status *s = arg;
    char attempts[16], progress[32], error[16], caveats[16];
    snprintf(attempts, sizeof attempts, "%d", s->attempts);
    snprintf(progress, sizeof progress, "%.6f", s->progress);
    snprintf(error, sizeof error, "%d", s->error);
    snprintf(caveats, sizeof caveats, "%u", s->caveats);
    const char *values[] = {s->id, s->owner, attempts, sdfd_job_state_name(s->state),
                            progress, error, s->message, caveats, s->warning};
    PGresult *r = NULL;
    int rc = exec(conn, m, END, 9, values, &r, err, cap);
    if (!rc && atoi(PQcmdTuples(r)) != 1)
        rc = SDF_ENOTFOUND, snprintf(err, cap, "job %s is no longer this replica's", s->id);
    PQclear(r);
    return rc;
}

int sdfd_catjobs_end(sdfd_catalog *c, const sdfd_job_status *s, char *err, size_t cap)
{
    return sdfd_catalog_transact(c, 1, end_call, (void *)s, err, cap);
}

/* ---- cancel and expiry ------------------------------------------------------------------ */

static int cancel_call(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err, size_t cap)
{
    read_args *a = arg;
    const char *values[] = {a->id};
    PGresult *r = NULL;
    int rc = exec(conn, m, LOCK_ONE, 1, values, &r, err, cap);
    if (!rc && PQntuples(r) != 1)
        rc = SDF_ENOTFOUND, snprintf(err, cap, "no job '%s'", a->id);
    char state[16] = "";
    if (!rc)
        copy_field(state, sizeof state, r, 0, 0);
    PQclear(r);
    const char *change = !strcmp(state, "queued")    ? CANCEL_QUEUED
                         : !strcmp(state, "running") ? CANCEL_RUNNING
                                                     : NULL;
    if (!rc && change)
        rc = exec(conn, m, change, 1, values, NULL, err, cap);
    if (!rc)
        rc = get_call(conn, m, a, err, cap);
    if (!rc && !change) /* finished: forgotten, answered with what it was */
        rc = exec(conn, m, FORGET, 1, values, NULL, err, cap);
    return rc;
}

int sdfd_catjobs_cancel(sdfd_catalog *c, const char *id, sdfd_job_status *out, char *err,
                        size_t cap)
{
    read_args a = {.id = id, .one = out};
    return sdfd_catalog_transact(c, 1, cancel_call, &a, err, cap);
}

typedef struct expire_args {
    size_t requeued, failed;
} expire_args;

static int expire_call(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err, size_t cap)
{
    expire_args *a = arg;
    char code[16];
    snprintf(code, sizeof code, "%d", SDFD_EUNAVAILABLE);
    const char *values[] = {code, "owner replica lost: the replicas that ran it stopped "
                                  "renewing its lease twice; post it again"};
    PGresult *r = NULL;
    int rc = exec(conn, m, EXPIRE, 2, values, &r, err, cap);
    a->requeued = a->failed = 0;
    for (int i = 0; !rc && i < PQntuples(r); i++) {
        if (!strcmp(PQgetvalue(r, i, 0), "queued"))
            a->requeued++;
        else
            a->failed++;
    }
    PQclear(r);
    return rc;
}

int sdfd_catjobs_expire(sdfd_catalog *c, size_t *requeued, size_t *failed, char *err,
                        size_t cap)
{
    expire_args a = {0, 0};
    int rc = sdfd_catalog_transact(c, 1, expire_call, &a, err, cap);
    *requeued = a.requeued, *failed = a.failed;
    return rc;
}
