/* cutproxy.c - the cutting proxy of cutproxy.h: one thread, poll() over the two ends of the
 * current connection, blocking writes (the bytes in play are a few megabytes at most). */
#include "cutproxy.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

static int write_all(int fd, const char *buf, size_t n)
{
    while (n > 0) {
        ssize_t w = send(fd, buf, n, MSG_NOSIGNAL);
        if (w <= 0)
            return -1;
        buf += w;
        n -= (size_t)w;
    }
    return 0;
}

static int connect_upstream(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port),
                            .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    if (fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a)) {
        close(fd);
        return -1;
    }
    return fd;
}

/* Relay one connection until either end closes, the plan cuts it, or the proxy stops. */
static void relay(cut_proxy *p, int client, const cut_plan *plan)
{
    int server = connect_upstream(p->upstream_port);
    long replies = 0, requests = 0;
    static char buf[1 << 16];
    int cut = 0;
    while (server >= 0 && !p->stop && !cut) {
        struct pollfd f[2] = {{.fd = client, .events = POLLIN}, {.fd = server, .events = POLLIN}};
        if (poll(f, 2, 100) <= 0)
            continue;
        if (f[0].revents) {
            long want = plan->request_bytes < 0 ? (long)sizeof buf : plan->request_bytes - requests;
            ssize_t n = recv(client, buf, (size_t)(want < (long)sizeof buf ? want : (long)sizeof buf), 0);
            if (n <= 0 || write_all(server, buf, (size_t)n))
                break;
            requests += n;
            cut = plan->request_bytes >= 0 && requests >= plan->request_bytes;
        }
        if (f[1].revents && !cut) {
            long want = plan->reply_bytes < 0 ? (long)sizeof buf : plan->reply_bytes - replies;
            ssize_t n = recv(server, buf, (size_t)(want < (long)sizeof buf ? want : (long)sizeof buf), 0);
            if (n <= 0 || write_all(client, buf, (size_t)n))
                break;
            replies += n;
            cut = plan->reply_bytes >= 0 && replies >= plan->reply_bytes;
        }
    }
    if (cut && plan->reset) {
        struct linger l = {.l_onoff = 1, .l_linger = 0};
        setsockopt(client, SOL_SOCKET, SO_LINGER, &l, sizeof l);
    }
    close(client);
    if (server >= 0)
        close(server);
}

static void *serve(void *arg)
{
    cut_proxy *p = arg;
    while (!p->stop) {
        struct pollfd f = {.fd = p->listen_fd, .events = POLLIN};
        if (poll(&f, 1, 100) <= 0)
            continue;
        int client = accept(p->listen_fd, NULL, NULL);
        if (client < 0)
            continue;
        int i = p->connections++;
        relay(p, client, &p->plan[i < p->nplan ? i : p->nplan - 1]);
    }
    return NULL;
}

int cut_proxy_start(cut_proxy *p, int upstream_port, const cut_plan *plan, int nplan)
{
    memset(p, 0, sizeof *p);
    p->upstream_port = upstream_port;
    p->plan = plan;
    p->nplan = nplan;
    p->listen_fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof a;
    if (p->listen_fd < 0 || bind(p->listen_fd, (struct sockaddr *)&a, sizeof a) ||
        listen(p->listen_fd, 8) || getsockname(p->listen_fd, (struct sockaddr *)&a, &len) ||
        pthread_create(&p->thread, NULL, serve, p)) {
        if (p->listen_fd >= 0)
            close(p->listen_fd);
        return -1;
    }
    p->port = ntohs(a.sin_port);
    return 0;
}

void cut_proxy_stop(cut_proxy *p)
{
    p->stop = 1;
    pthread_join(p->thread, NULL);
    close(p->listen_fd);
}
