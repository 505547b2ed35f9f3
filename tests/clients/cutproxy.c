/* cutproxy.c - the cutting proxy of cutproxy.h: one thread, poll() over the two ends of the
 * current connection, blocking writes (the bytes in play are a few megabytes at most). The
 * refusing relay follows the frames both ways (proto.h's header), to take one request out
 * of the stream and put its ERROR between two replies. */
#include "cutproxy.h"

#include "proto.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdint.h>
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

/* Reset the connection at once: SO_LINGER 0 makes close() send RST. */
static void reset_now(int fd)
{
    struct linger l = {.l_onoff = 1, .l_linger = 0};
    setsockopt(fd, SOL_SOCKET, SO_LINGER, &l, sizeof l);
    close(fd);
}

/* Move what `from` has to `to`, no more than limit - *moved in all (limit < 0: no limit).
 * -1 when either end is gone, 1 when the limit is reached (the cut), else 0. */
static int pass_on(int from, int to, long limit, long *moved)
{
    static char buf[1 << 16];
    long want = limit < 0 ? (long)sizeof buf : limit - *moved;
    ssize_t n = recv(from, buf, (size_t)(want < (long)sizeof buf ? want : (long)sizeof buf), 0);
    if (n <= 0 || write_all(to, buf, (size_t)n))
        return -1;
    *moved += n;
    return limit >= 0 && *moved >= limit;
}

/* Relay one connection until either end closes, the plan cuts it, or the proxy stops. */
static void relay(cut_proxy *p, int client, const cut_plan *plan)
{
    int server = connect_upstream(p->upstream_port);
    long replies = 0, requests = 0;
    int cut = 0;
    while (server >= 0 && !p->stop && !cut) {
        struct pollfd f[2] = {{.fd = client, .events = POLLIN}, {.fd = server, .events = POLLIN}};
        if (poll(f, 2, 100) <= 0)
            continue;
        if (f[0].revents && (cut = pass_on(client, server, plan->request_bytes, &requests)) < 0)
            break;
        if (f[1].revents && !cut &&
            (cut = pass_on(server, client, plan->reply_bytes, &replies)) < 0)
            break;
    }
    if (cut > 0 && plan->reset) /* cut by the plan, not ended by one side */
        reset_now(client);
    else
        close(client);
    if (server >= 0)
        close(server);
}

/* Where one direction's stream stands: inside a frame's header (got < 16) or its payload
 * (`left` bytes to come); `drop`: this frame is not passed on. */
typedef struct framer {
    unsigned char hdr[SDF_PROTO_HEADER_SIZE];
    size_t got;
    uint32_t left;
    int drop;
} framer;

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* The next `n` bytes of `buf` through `f`: how many of them finish the current frame's
 * header or payload, at most up to the end of that frame (0 < result <= n). *frame_done:
 * the frame ended there; *header_done: its header, just read, is in f->hdr. */
static size_t frame_step(framer *f, const char *buf, size_t n, int *header_done,
                         int *frame_done)
{
    size_t take;
    *header_done = *frame_done = 0;
    if (f->got < SDF_PROTO_HEADER_SIZE) {
        take = SDF_PROTO_HEADER_SIZE - f->got < n ? SDF_PROTO_HEADER_SIZE - f->got : n;
        memcpy(f->hdr + f->got, buf, take);
        f->got += take;
        if (f->got == SDF_PROTO_HEADER_SIZE) {
            *header_done = 1;
            f->left = le32(f->hdr + 12);
        }
    } else {
        take = f->left < n ? f->left : n;
        f->left -= (uint32_t)take;
    }
    if (f->got == SDF_PROTO_HEADER_SIZE && f->left == 0) {
        *frame_done = 1;
        f->got = 0;
    }
    return take;
}

/* The unavailable relay (cutproxy.h): requests pass but the first query, whose ERROR goes
 * to the client once the server's replies stand between two frames. */
static void relay_refusing(cut_proxy *p, int client)
{
    int server = connect_upstream(p->upstream_port);
    static char buf[1 << 16];
    unsigned char error[256];
    size_t error_len = 0;
    int refused = 0;
    framer up = {0}, down = {0};
    while (server >= 0 && !p->stop) {
        struct pollfd f[2] = {{.fd = client, .events = POLLIN}, {.fd = server, .events = POLLIN}};
        if (poll(f, 2, 100) <= 0)
            continue;
        if (f[0].revents) {
            ssize_t n = recv(client, buf, sizeof buf, 0);
            if (n <= 0)
                break;
            for (size_t at = 0; at < (size_t)n;) {
                int head, done;
                size_t take = frame_step(&up, buf + at, (size_t)n - at, &head, &done);
                if (head) {
                    uint8_t type = up.hdr[5];
                    up.drop = !refused && (type == SDF_PROTO_QUERY || type == SDF_PROTO_VOLUME_QUERY);
                    if (up.drop) {
                        refused = 1;
                        error_len = sdf_proto_encode_error(error, sizeof error, le32(up.hdr + 8),
                                                           503, "EUNAVAILABLE",
                                                           "the server is shutting down");
                    } else if (write_all(server, (const char *)up.hdr, sizeof up.hdr)) {
                        goto out;
                    }
                } else if (up.got == SDF_PROTO_HEADER_SIZE || done) {
                    if (!up.drop && write_all(server, buf + at, take))
                        goto out;
                }
                at += take;
            }
        }
        if (f[1].revents) {
            ssize_t n = recv(server, buf, sizeof buf, 0);
            if (n <= 0)
                break;
            size_t from = 0;
            for (size_t at = 0; at < (size_t)n;) {
                int head, done;
                at += frame_step(&down, buf + at, (size_t)n - at, &head, &done);
                if (done && error_len) { /* between two replies: the refusal goes in */
                    if (write_all(client, buf + from, at - from) ||
                        write_all(client, (const char *)error, error_len))
                        goto out;
                    from = at;
                    error_len = 0;
                }
            }
            if (write_all(client, buf + from, (size_t)n - from))
                break;
        }
        /* the server idle between replies: the refusal need not wait */
        if (error_len && down.got == 0) {
            if (write_all(client, (const char *)error, error_len))
                break;
            error_len = 0;
        }
    }
out:
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
        const cut_plan *plan = &p->plan[i < p->nplan ? i : p->nplan - 1];
        if (plan->accept_reset)
            reset_now(client);
        else if (plan->unavailable)
            relay_refusing(p, client);
        else
            relay(p, client, plan);
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
