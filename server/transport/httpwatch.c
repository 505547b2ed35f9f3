/* httpwatch.c - deadlines for HTTP requests to arrive (httpwatch.h): one record per
 * connection, made and dropped by MHD's connection notifications, and a thread that looks
 * at them four times a second and shuts down the socket of a request past its deadline.
 * MHD sees the shutdown as the client leaving and closes the connection on its own thread,
 * so the descriptor stays MHD's: the record is dropped (under the lock the thread holds
 * while it shuts sockets down) before MHD closes it, and its number cannot be reused for
 * another connection while the thread may still act on it. */
#include "transport/httpwatch.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <time.h>

#include "core/log.h"

typedef struct watched {
    struct watched *prev, *next;
    int fd;
    double since; /* when the request being received began; 0 when none is */
    size_t got;   /* its body bytes so far */
    int cut;      /* shut down already */
} watched;

struct sdfd_httpwatch {
    pthread_mutex_t lock;
    pthread_cond_t wake;
    pthread_t thread;
    int stop;
    double timeout;
    watched *list;
};

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void cut_overdue(sdfd_httpwatch *w)
{
    double now = now_seconds();
    int cut = 0;
    for (watched *e = w->list; e; e = e->next) {
        if (e->cut || !e->since || now - e->since <= w->timeout + (double)e->got / SDFD_HTTP_MIN_RATE)
            continue;
        shutdown(e->fd, SHUT_RDWR);
        e->cut = 1;
        cut++;
    }
    if (cut)
        sdfd_log("warn", "http_deadline", "cut off %d connection(s) whose request took over "
                 "--timeout %.0f s (plus 1 s per %.0f body bytes) to arrive", cut, w->timeout,
                 SDFD_HTTP_MIN_RATE);
}

static void *watch_loop(void *arg)
{
    sdfd_httpwatch *w = arg;
    pthread_mutex_lock(&w->lock);
    while (!w->stop) {
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        until.tv_nsec += 250000000L;
        if (until.tv_nsec >= 1000000000L)
            until.tv_sec++, until.tv_nsec -= 1000000000L;
        int rc = pthread_cond_timedwait(&w->wake, &w->lock, &until);
        if (rc == ETIMEDOUT && !w->stop)
            cut_overdue(w);
    }
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

sdfd_httpwatch *sdfd_httpwatch_start(unsigned timeout_seconds)
{
    sdfd_httpwatch *w = calloc(1, sizeof *w);
    if (!w)
        return NULL;
    w->timeout = timeout_seconds;
    pthread_mutex_init(&w->lock, NULL);
    pthread_cond_init(&w->wake, NULL);
    if (pthread_create(&w->thread, NULL, watch_loop, w)) {
        pthread_cond_destroy(&w->wake);
        pthread_mutex_destroy(&w->lock);
        free(w);
        return NULL;
    }
    return w;
}

void sdfd_httpwatch_stop(sdfd_httpwatch *w)
{
    if (!w)
        return;
    pthread_mutex_lock(&w->lock);
    w->stop = 1;
    pthread_cond_signal(&w->wake);
    pthread_mutex_unlock(&w->lock);
    pthread_join(w->thread, NULL);
    for (watched *e = w->list, *next; e; e = next) {
        next = e->next;
        free(e);
    }
    pthread_cond_destroy(&w->wake);
    pthread_mutex_destroy(&w->lock);
    free(w);
}

void sdfd_httpwatch_notify(void *cls, struct MHD_Connection *conn, void **entry,
                           enum MHD_ConnectionNotificationCode code)
{
    sdfd_httpwatch *w = cls;
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        const union MHD_ConnectionInfo *info =
            MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CONNECTION_FD);
        watched *e = info ? calloc(1, sizeof *e) : NULL;
        *entry = e;
        if (!e)
            return; /* unwatched: MHD's idle timeout still applies */
        e->fd = info->connect_fd;
        e->since = now_seconds();
        pthread_mutex_lock(&w->lock);
        e->next = w->list;
        if (w->list)
            w->list->prev = e;
        w->list = e;
        pthread_mutex_unlock(&w->lock);
        return;
    }
    watched *e = *entry;
    if (!e)
        return;
    pthread_mutex_lock(&w->lock);
    if (e->prev)
        e->prev->next = e->next;
    else
        w->list = e->next;
    if (e->next)
        e->next->prev = e->prev;
    pthread_mutex_unlock(&w->lock);
    free(e);
    *entry = NULL;
}

/* The connection's entry: its socket context begins with the pointer notify filled. */
static watched *record(struct MHD_Connection *conn)
{
    const union MHD_ConnectionInfo *info =
        MHD_get_connection_info(conn, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    void **context = info ? info->socket_context : NULL;
    return context ? *context : NULL;
}

void sdfd_httpwatch_received(sdfd_httpwatch *w, struct MHD_Connection *conn, size_t bytes)
{
    watched *e = record(conn);
    if (!e)
        return;
    pthread_mutex_lock(&w->lock);
    e->got += bytes;
    pthread_mutex_unlock(&w->lock);
}

void sdfd_httpwatch_arrived(sdfd_httpwatch *w, struct MHD_Connection *conn)
{
    watched *e = record(conn);
    if (!e)
        return;
    pthread_mutex_lock(&w->lock);
    e->since = 0;
    pthread_mutex_unlock(&w->lock);
}

void sdfd_httpwatch_next(sdfd_httpwatch *w, struct MHD_Connection *conn)
{
    watched *e = record(conn);
    if (!e)
        return;
    pthread_mutex_lock(&w->lock);
    e->since = now_seconds(), e->got = 0;
    pthread_mutex_unlock(&w->lock);
}
