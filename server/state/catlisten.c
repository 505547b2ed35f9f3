/* catlisten.c - the catalog's notification listener (see catlisten.h).
 *
 * The thread waits in poll on two descriptors: the connection's socket and the read end of
 * a pipe that sdfd_catlisten_stop writes to. Once written the pipe stays readable, so every
 * wait after it, the backoff's and the connect's included, ends at once. libpq reads what the
 * socket holds in PQconsumeInput and queues the notifications for PQnotifies; a read that
 * fails, or a connection libpq marks bad, is a lost connection: close, reconnect, resync. */
#include "state/catlisten.h"

#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/errors.h"
#include "core/log.h"
#include "state/catconn.h"

#define BACKOFF_FIRST 0.1
#define BACKOFF_MAX 5.0

struct sdfd_catlisten {
    char *conninfo;
    sdfd_catlisten_callbacks cb;
    sdfd_catalog_metrics *metrics, own;
    int wake[2]; /* [0] polled, [1] written by stop */
    pthread_t thread;
};

int sdfd_catlisten_parse(const char *payload, sdfd_item_kind *kind, char *name, size_t cap,
                         uint64_t *version, int *deleted)
{
    const char *p = payload;
    if (!strncmp(p, "mesh ", 5))
        *kind = SDFD_ITEM_MESH, p += 5;
    else if (!strncmp(p, "volume ", 7))
        *kind = SDFD_ITEM_VOLUME, p += 7;
    else
        return -1;
    if (*p < '1' || *p > '9')
        return -1;
    char *end;
    errno = 0;
    *version = strtoull(p, &end, 10);
    if (errno || (strncmp(end, " put ", 5) && strncmp(end, " del ", 5)))
        return -1;
    *deleted = end[1] == 'd';
    p = end + 5;
    size_t len = strlen(p);
    if (len >= cap || !sdfd_valid_name(p, len))
        return -1;
    memcpy(name, p, len + 1);
    return 0;
}

/* Wait up to `seconds` for the stop signal: 1 when it came. */
static int stopped_within(sdfd_catlisten *l, double seconds)
{
    struct pollfd fd = {l->wake[0], POLLIN, 0};
    int r;
    while ((r = poll(&fd, 1, (int)(seconds * 1000))) < 0 && errno == EINTR)
        ;
    return r > 0;
}

static void deliver(sdfd_catlisten *l, PGconn *conn)
{
    PGnotify *n;
    while ((n = PQnotifies(conn))) {
        sdfd_item_kind kind;
        char name[SDFD_MAX_NAME + 1];
        uint64_t version;
        int deleted;
        if (!strcmp(n->relname, SDFD_CATALOG_CHANNEL) &&
            !sdfd_catlisten_parse(n->extra, &kind, name, sizeof name, &version, &deleted)) {
            atomic_fetch_add(&l->metrics->notifications, 1);
            if (l->cb.change)
                l->cb.change(l->cb.arg, kind, name, version, deleted);
        }
        PQfreemem(n);
    }
}

/* Serve notifications until the connection is lost (0) or stop is called (1). */
static int listen_until_lost(sdfd_catlisten *l, PGconn *conn)
{
    atomic_store(&l->metrics->listening, 1);
    atomic_fetch_add(&l->metrics->resyncs, 1);
    if (l->cb.resync)
        l->cb.resync(l->cb.arg);
    for (;;) {
        deliver(l, conn);
        struct pollfd fds[2] = {{PQsocket(conn), POLLIN, 0}, {l->wake[0], POLLIN, 0}};
        if (poll(fds, 2, -1) < 0 && errno != EINTR)
            return 0;
        if (fds[1].revents)
            return 1;
        if (fds[0].revents && (!PQconsumeInput(conn) || PQstatus(conn) != CONNECTION_OK)) {
            deliver(l, conn); /* what arrived before the end was committed */
            return 0;
        }
    }
}

/* Connect and LISTEN: 0 with *conn set, SDF_ECANCELED on stop, or another code (err). */
static int connect_listening(sdfd_catlisten *l, PGconn **conn, char *err, size_t cap)
{
    int rc = sdfd_catconn_open(l->conninfo, l->wake[0], l->metrics, conn, err, cap);
    if (!rc)
        rc = sdfd_catconn_exec(l->metrics, *conn, "LISTEN " SDFD_CATALOG_CHANNEL, 0, NULL, NULL,
                               NULL, 0, NULL, err, cap);
    if (rc && *conn) {
        PQfinish(*conn);
        *conn = NULL;
    }
    return rc;
}

static void *listener_main(void *arg)
{
    sdfd_catlisten *l = arg;
    double backoff = BACKOFF_FIRST;
    int failing = 0;
    for (;;) {
        PGconn *conn = NULL;
        char err[512];
        int rc = connect_listening(l, &conn, err, sizeof err);
        if (rc == SDF_ECANCELED)
            break;
        if (rc) {
            if (!failing++)
                sdfd_log("warn", "catalog_listen", "%s; retrying with backoff", err);
            if (stopped_within(l, backoff))
                break;
            backoff = backoff * 2 < BACKOFF_MAX ? backoff * 2 : BACKOFF_MAX;
            continue;
        }
        if (failing)
            sdfd_log("info", "catalog_listen", "listening again after %d failed attempts",
                     failing);
        failing = 0, backoff = BACKOFF_FIRST;
        int stop = listen_until_lost(l, conn);
        atomic_store(&l->metrics->listening, 0);
        if (!stop) {
            sdfd_catconn_message(err, sizeof err, "connection lost", PQerrorMessage(conn));
            sdfd_log("warn", "catalog_listen", "%s; reconnecting", err);
        }
        PQfinish(conn);
        if (stop)
            break;
    }
    return NULL;
}

int sdfd_catlisten_start(const char *conninfo, const sdfd_catlisten_callbacks *cb,
                         sdfd_catalog_metrics *m, sdfd_catlisten **out, char *err, size_t cap)
{
    *out = NULL;
    int rc = sdfd_catconn_check(conninfo, err, cap);
    if (rc)
        return rc;
    sdfd_catlisten *l = calloc(1, sizeof *l);
    if (!l || !(l->conninfo = strdup(conninfo)) || pipe(l->wake)) {
        if (l)
            free(l->conninfo);
        free(l);
        snprintf(err, cap, "cannot start the catalog listener: out of memory or descriptors");
        return SDF_ENOMEM;
    }
    l->cb = *cb;
    l->metrics = m ? m : &l->own;
    if ((rc = pthread_create(&l->thread, NULL, listener_main, l))) {
        snprintf(err, cap, "cannot start the catalog listener: %s", strerror(rc));
        close(l->wake[0]);
        close(l->wake[1]);
        free(l->conninfo);
        free(l);
        return SDF_ENOMEM;
    }
    *out = l;
    return 0;
}

void sdfd_catlisten_stop(sdfd_catlisten *l)
{
    if (!l)
        return;
    ssize_t w;
    while ((w = write(l->wake[1], "x", 1)) < 0 && errno == EINTR)
        ;
    pthread_join(l->thread, NULL);
    close(l->wake[0]);
    close(l->wake[1]);
    free(l->conninfo);
    free(l);
}
