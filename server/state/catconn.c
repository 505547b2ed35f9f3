/* catconn.c - opening, pooling and using connections to PostgreSQL (see catconn.h).
 *
 * The pool is a mutex-protected stack of idle connections and a count of those that exist;
 * a caller takes one, runs its statements alone on it and gives it back. Connections are
 * opened lazily and closed whenever they may be unhealthy, which is how a restarted server
 * is recovered from without anyone noticing but the call that met the failure: an idle
 * connection with anything to read has been told something unprompted (a shutdown's FATAL,
 * or the end of the stream), so it is closed before use rather than failing a call. */
#include "state/catconn.h"

#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/errors.h"

struct sdfd_catconn_pool {
    pthread_mutex_t lock;
    pthread_cond_t freed;
    char *conninfo;
    sdfd_catalog_metrics *metrics;
    size_t max, open; /* connections allowed; existing (idle or in use) */
    size_t n_idle;
    PGconn **idle;    /* max entries */
};

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

void sdfd_catconn_message(char *err, size_t cap, const char *what, const char *msg)
{
    if (cap == 0)
        return;
    int n = snprintf(err, cap, "%s: ", what);
    size_t len = n < 0 ? 0 : (size_t)n < cap ? (size_t)n : cap - 1;
    /* libpq's lines ("...failed: Connection refused\n\tIs the server running...") as one */
    for (const char *p = msg && *msg ? msg : "no message"; *p && len + 1 < cap; p++) {
        char ch = *p == '\n' || *p == '\t' ? ' ' : *p;
        if (ch != ' ' || (len > 0 && err[len - 1] != ' '))
            err[len++] = ch;
    }
    while (len > 0 && err[len - 1] == ' ')
        len--;
    err[len] = '\0';
}

static void quiet_notices(void *arg, const char *message)
{
    (void)arg, (void)message; /* "relation already exists, skipping" and the like */
}

int sdfd_catconn_check(const char *conninfo, char *err, size_t cap)
{
    char *msg = NULL;
    PQconninfoOption *opts = PQconninfoParse(conninfo ? conninfo : "", &msg);
    if (!opts) {
        sdfd_catconn_message(err, cap, "invalid catalog connection string",
                             msg ? msg : "out of memory");
        PQfreemem(msg);
        return msg ? SDF_EINVAL : SDF_ENOMEM;
    }
    PQconninfoFree(opts);
    return 0;
}

/* The connect_timeout the string names, or SDFD_CATCONN_TIMEOUT_SECONDS. */
static double connect_timeout(const char *conninfo)
{
    double seconds = SDFD_CATCONN_TIMEOUT_SECONDS;
    PQconninfoOption *opts = PQconninfoParse(conninfo, NULL);
    for (PQconninfoOption *o = opts; o && o->keyword; o++)
        if (!strcmp(o->keyword, "connect_timeout") && o->val && atoi(o->val) > 0)
            seconds = atoi(o->val);
    PQconninfoFree(opts);
    return seconds;
}

/* Drive PQconnectPoll until the connection is made, fails, times out or wake_fd wakes. */
static int finish_connect(PGconn *conn, int wake_fd, double deadline, char *err, size_t cap)
{
    PostgresPollingStatusType st = PGRES_POLLING_WRITING;
    while (st != PGRES_POLLING_OK) {
        if (st == PGRES_POLLING_FAILED) {
            sdfd_catconn_message(err, cap, "catalog unavailable", PQerrorMessage(conn));
            return SDFD_EUNAVAILABLE;
        }
        struct pollfd fds[2] = {{PQsocket(conn), st == PGRES_POLLING_READING ? POLLIN : POLLOUT, 0},
                                {wake_fd, POLLIN, 0}};
        double left = deadline - now_seconds();
        if (left <= 0) {
            snprintf(err, cap, "catalog unavailable: connecting timed out");
            return SDFD_EUNAVAILABLE;
        }
        int r = poll(fds, wake_fd >= 0 ? 2 : 1, (int)(left * 1000) + 1);
        if (r < 0 && errno != EINTR) {
            snprintf(err, cap, "catalog unavailable: poll: %s", strerror(errno));
            return SDFD_EUNAVAILABLE;
        }
        if (wake_fd >= 0 && (fds[1].revents & POLLIN)) {
            snprintf(err, cap, "connecting to the catalog canceled");
            return SDF_ECANCELED;
        }
        if (r > 0)
            st = PQconnectPoll(conn);
    }
    return 0;
}

int sdfd_catconn_open(const char *conninfo, int wake_fd, sdfd_catalog_metrics *m, PGconn **out,
                      char *err, size_t cap)
{
    /* sdfd's defaults first: the expanded string that follows overrides them. */
    static const char *const keys[] = {"keepalives", "keepalives_idle", "keepalives_interval",
                                       "keepalives_count", "application_name", "dbname", NULL};
    const char *values[] = {"1", "30", "10", "3", "sdfd", conninfo, NULL};
    *out = NULL;
    PGconn *conn = PQconnectStartParams(keys, values, 1);
    if (!conn) {
        snprintf(err, cap, "out of memory connecting to the catalog");
        return SDF_ENOMEM;
    }
    int rc = PQstatus(conn) == CONNECTION_BAD ? SDFD_EUNAVAILABLE : 0;
    if (rc)
        sdfd_catconn_message(err, cap, "catalog unavailable", PQerrorMessage(conn));
    else
        rc = finish_connect(conn, wake_fd, now_seconds() + connect_timeout(conninfo), err, cap);
    if (m) {
        atomic_fetch_add(rc ? &m->connect_failures : &m->connects, 1);
        if (rc != SDF_ECANCELED)
            atomic_store(&m->up, rc == 0);
        if (rc == SDFD_EUNAVAILABLE)
            atomic_fetch_add(&m->unavailable, 1);
    }
    if (rc) {
        PQfinish(conn);
        return rc;
    }
    PQsetNoticeProcessor(conn, quiet_notices, NULL);
    *out = conn;
    return 0;
}

sdfd_catconn_pool *sdfd_catconn_pool_create(const char *conninfo, size_t max_conns,
                                            sdfd_catalog_metrics *m)
{
    sdfd_catconn_pool *p = calloc(1, sizeof *p);
    if (!p)
        return NULL;
    p->max = max_conns ? max_conns : 4;
    p->conninfo = strdup(conninfo);
    p->idle = calloc(p->max, sizeof *p->idle);
    if (!p->conninfo || !p->idle) {
        free(p->conninfo);
        free(p->idle);
        free(p);
        return NULL;
    }
    p->metrics = m;
    pthread_mutex_init(&p->lock, NULL);
    pthread_cond_init(&p->freed, NULL);
    return p;
}

void sdfd_catconn_pool_destroy(sdfd_catconn_pool *p)
{
    if (!p)
        return;
    for (size_t i = 0; i < p->n_idle; i++)
        PQfinish(p->idle[i]);
    pthread_mutex_destroy(&p->lock);
    pthread_cond_destroy(&p->freed);
    free(p->idle);
    free(p->conninfo);
    free(p);
}

/* An idle connection has nothing to read unless the server said something unprompted
 * (it is shutting down) or closed it: either way it is of no further use. */
static int looks_alive(PGconn *conn)
{
    if (PQstatus(conn) != CONNECTION_OK || PQtransactionStatus(conn) != PQTRANS_IDLE)
        return 0;
    struct pollfd fd = {PQsocket(conn), POLLIN, 0};
    return fd.fd >= 0 && poll(&fd, 1, 0) == 0;
}

/* Close a connection the pool counted. */
static void discard(sdfd_catconn_pool *p, PGconn *conn)
{
    PQfinish(conn);
    pthread_mutex_lock(&p->lock);
    p->open--;
    pthread_cond_signal(&p->freed);
    pthread_mutex_unlock(&p->lock);
}

int sdfd_catconn_get(sdfd_catconn_pool *p, PGconn **out, int *reused, char *err, size_t cap)
{
    for (;;) {
        pthread_mutex_lock(&p->lock);
        while (p->n_idle == 0 && p->open >= p->max)
            pthread_cond_wait(&p->freed, &p->lock);
        PGconn *conn = p->n_idle ? p->idle[--p->n_idle] : NULL;
        if (!conn)
            p->open++; /* a place for the one we open */
        pthread_mutex_unlock(&p->lock);
        if (conn && looks_alive(conn)) {
            *out = conn, *reused = 1;
            return 0;
        }
        if (conn) {
            discard(p, conn);
            continue;
        }
        int rc = sdfd_catconn_open(p->conninfo, -1, p->metrics, out, err, cap);
        if (rc) {
            pthread_mutex_lock(&p->lock);
            p->open--;
            pthread_cond_signal(&p->freed);
            pthread_mutex_unlock(&p->lock);
            return rc;
        }
        *reused = 0;
        return 0;
    }
}

void sdfd_catconn_put(sdfd_catconn_pool *p, PGconn *conn)
{
    if (!conn)
        return;
    if (PQstatus(conn) != CONNECTION_OK || PQtransactionStatus(conn) != PQTRANS_IDLE) {
        discard(p, conn);
        return;
    }
    pthread_mutex_lock(&p->lock);
    p->idle[p->n_idle++] = conn; /* n_idle < open <= max */
    pthread_cond_signal(&p->freed);
    pthread_mutex_unlock(&p->lock);
}

/* Is this SQLSTATE one of a server that is unreachable, short of resources or going away? */
static int state_unavailable(const char *s)
{
    return !s || !strncmp(s, "08", 2) || !strncmp(s, "53", 2) || !strncmp(s, "57P", 3) ||
           !strcmp(s, "55P03") /* lock_not_available */ || !strcmp(s, "57014") /* canceled */;
}

int sdfd_catconn_error(sdfd_catalog_metrics *m, PGconn *conn, const PGresult *res,
                       const char *what, char *err, size_t cap)
{
    const char *state = res ? PQresultErrorField(res, PG_DIAG_SQLSTATE) : NULL;
    const char *msg = res && *PQresultErrorMessage(res) ? PQresultErrorMessage(res)
                                                         : PQerrorMessage(conn);
    if (state && (!strcmp(state, "40001") || !strcmp(state, "40P01"))) {
        sdfd_catconn_message(err, cap, what, msg);
        return SDFD_CATCONN_RETRY;
    }
    if (state && !strncmp(state, "23", 2) && PQstatus(conn) == CONNECTION_OK) {
        sdfd_catconn_message(err, cap, what, msg);
        return SDFD_CATCONN_CONFLICT;
    }
    if (PQstatus(conn) != CONNECTION_OK || state_unavailable(state)) {
        char head[160];
        snprintf(head, sizeof head, "catalog unavailable (%s)", what);
        sdfd_catconn_message(err, cap, head, msg);
        if (m) {
            atomic_fetch_add(&m->unavailable, 1);
            atomic_store(&m->up, PQstatus(conn) == CONNECTION_OK);
        }
        return SDFD_EUNAVAILABLE;
    }
    char head[160];
    snprintf(head, sizeof head, "catalog error (%s, SQLSTATE %s)", what, state);
    sdfd_catconn_message(err, cap, head, msg);
    return SDF_EIO;
}

int sdfd_catconn_exec(sdfd_catalog_metrics *m, PGconn *conn, const char *sql, int n,
                      const char *const *values, const int *lengths, const int *formats,
                      int binary, PGresult **res, char *err, size_t cap)
{
    double t0 = now_seconds();
    PGresult *r = PQexecParams(conn, sql, n, NULL, values, lengths, formats, binary);
    if (m)
        sdfd_catalog_metrics_round_trip(m, now_seconds() - t0);
    ExecStatusType st = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
    if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK) {
        if (m)
            atomic_store(&m->up, 1);
        if (res)
            *res = r;
        else
            PQclear(r);
        return 0;
    }
    int rc = sdfd_catconn_error(m, conn, r, "statement", err, cap);
    PQclear(r);
    return rc;
}

/* Read results until libpq has none left, so the connection is ready for the next call. */
static void drain(PGconn *conn)
{
    PGresult *r;
    while ((r = PQgetResult(conn)))
        PQclear(r);
}

int sdfd_catconn_stream(sdfd_catalog_metrics *m, PGconn *conn, const char *sql, int n,
                        const char *const *values, const int *lengths, const int *formats,
                        int binary, sdfd_catconn_row_fn row, void *arg, char *err, size_t cap)
{
    double t0 = now_seconds();
    if (!PQsendQueryParams(conn, sql, n, NULL, values, lengths, formats, binary))
        return sdfd_catconn_error(m, conn, NULL, "sending a query", err, cap);
    PQsetSingleRowMode(conn); /* may fail only after a send that failed */
    int rc = 0, complete = 0;
    PGresult *r;
    while (!rc && !complete && (r = PQgetResult(conn))) {
        ExecStatusType st = PQresultStatus(r);
        if (st == PGRES_SINGLE_TUPLE)
            rc = row(arg, r, err, cap);
        else if (st == PGRES_TUPLES_OK)
            complete = 1;
        else
            rc = sdfd_catconn_error(m, conn, r, "reading rows", err, cap);
        PQclear(r);
    }
    if (!rc && !complete) /* libpq ran out of results before the end: the connection broke */
        rc = sdfd_catconn_error(m, conn, NULL, "reading rows", err, cap);
    drain(conn);
    if (m) {
        sdfd_catalog_metrics_round_trip(m, now_seconds() - t0);
        if (!rc)
            atomic_store(&m->up, 1);
    }
    return rc;
}
