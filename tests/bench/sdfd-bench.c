/* sdfd-bench - throughput and latency of a running sdfd, for comparison with the in-process
 * sdf-bench on the same points (tests/bench/server-compare.sh runs both). Not a test.
 *
 *   sdfd-bench MESH|demo [POINTS.npy] --http HOST:PORT --bin HOST:PORT [--name NAME]
 *              [--form binary|octet|json] [--clients C] [--per-request K]
 *              [--workload band --n N --seed S] [--repeat R]
 *
 * MESH is loaded locally only to generate the workload (as sdf-bench does); the server must
 * serve it as NAME (default: demo). With --clients 1 (default) the whole point set goes in
 * one request, sent once untimed (a warm-up, as sdf-bench's: a fresh server's first large
 * buffers come from fresh pages), then timed R times (best reported). With C clients, each
 * thread sends requests of K points (default 1000) until all points are done; reported:
 * aggregate throughput and per-request latency percentiles. Request bodies are encoded before timing, and replies
 * are received in full but not parsed: the numbers are the server's cost plus transport.
 * The last line is `throughput: X Mq/s`. */
#define _GNU_SOURCE /* strcasestr */
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "../common/files.h"
#include "../common/workload.h"
#include "proto.h"

typedef enum form { BINARY, OCTET, JSON } form;

typedef struct options {
    const char *mesh, *points, *http, *bin, *name, *workload;
    form form;
    int clients, repeat;
    size_t per_request, n;
    uint64_t seed;
} options;

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void die(const char *what)
{
    fprintf(stderr, "sdfd-bench: %s\n", what);
    exit(1);
}

static int connect_to(const char *addr)
{
    char host[256], port[16];
    const char *colon = strrchr(addr, ':');
    if (!colon || (size_t)(colon - addr) >= sizeof host)
        die("address must be HOST:PORT");
    snprintf(host, sizeof host, "%.*s", (int)(colon - addr), addr);
    snprintf(port, sizeof port, "%s", colon + 1);
    struct addrinfo hints = {.ai_socktype = SOCK_STREAM}, *res;
    if (getaddrinfo(host, port, &hints, &res))
        die("cannot resolve the server address");
    int fd = socket(res->ai_family, SOCK_STREAM, 0);
    if (fd < 0 || connect(fd, res->ai_addr, res->ai_addrlen))
        die("cannot connect to the server");
    freeaddrinfo(res);
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    return fd;
}

static void send_all(int fd, const char *p, size_t n)
{
    while (n) {
        ssize_t k = send(fd, p, n, MSG_NOSIGNAL);
        if (k <= 0)
            die("send failed");
        p += k, n -= (size_t)k;
    }
}

static void recv_all(int fd, char *p, size_t n)
{
    while (n) {
        ssize_t k = recv(fd, p, n, 0);
        if (k <= 0)
            die("the server closed the connection");
        p += k, n -= (size_t)k;
    }
}

/* ---- requests, encoded before timing ----------------------------------------------------- */

typedef struct request {
    char *data;
    size_t len;
    size_t points;
} request;

static request encode(const options *o, const float *p, size_t n, uint32_t id)
{
    request r = {.points = n};
    if (o->form == BINARY) {
        sdf_proto_query q = {.mode = SDF_MODE_SIGNED, .sign = SDF_SIGN_AUTO, .name = o->name,
                             .name_len = strlen(o->name), .count = (uint32_t)n, .points = p};
        size_t cap = SDF_PROTO_HEADER_SIZE + sdf_proto_query_size(&q);
        r.data = malloc(cap);
        r.len = sdf_proto_encode_query(r.data, cap, id, &q);
        return r;
    }
    char *body;
    size_t body_len;
    if (o->form == OCTET) {
        body = (char *)p;
        body_len = 12 * n;
    } else {
        body = malloc(40 * 3 * n + 32);
        body_len = (size_t)sprintf(body, "{\"points\":[");
        for (size_t i = 0; i < 3 * n; i++)
            body_len += (size_t)sprintf(body + body_len, i ? ",%.9g" : "%.9g", (double)p[i]);
        body_len += (size_t)sprintf(body + body_len, "]}");
    }
    char head[256];
    int h = snprintf(head, sizeof head,
                     "POST /v1/meshes/%s/query HTTP/1.1\r\nHost: sdfd\r\nContent-Type: %s\r\n"
                     "Content-Length: %zu\r\n\r\n",
                     o->name, o->form == OCTET ? "application/octet-stream" : "application/json",
                     body_len);
    r.data = malloc((size_t)h + body_len);
    memcpy(r.data, head, (size_t)h);
    memcpy(r.data + h, body, body_len);
    r.len = (size_t)h + body_len;
    if (o->form == JSON)
        free(body);
    return r;
}

static __thread char *thread_buf;
static __thread size_t thread_cap;

static char *scratch(size_t n)
{
    if (n > thread_cap) {
        thread_buf = realloc(thread_buf, n);
        thread_cap = n;
    }
    return thread_buf;
}

/* Send one request and read its whole reply. */
static void roundtrip(const options *o, int fd, const request *r)
{
    send_all(fd, r->data, r->len);
    if (o->form == BINARY) {
        char head[SDF_PROTO_HEADER_SIZE];
        recv_all(fd, head, sizeof head);
        sdf_proto_header h;
        if (sdf_proto_decode_header(head, sizeof head, UINT32_MAX, &h, NULL) || h.type != SDF_PROTO_RESULT)
            die("unexpected binary reply");
        recv_all(fd, scratch(h.length), h.length);
        return;
    }
    /* HTTP: headers up to the blank line, then Content-Length bytes. */
    size_t got = 0, cap = 8192;
    char *buf = scratch(cap);
    char *end = NULL;
    while (!end) {
        ssize_t k = recv(fd, buf + got, cap - got - 1, 0);
        if (k <= 0)
            die("the server closed the connection");
        got += (size_t)k;
        buf[got] = '\0';
        end = strstr(buf, "\r\n\r\n");
        if (!end && got + 1 >= cap)
            die("reply headers too long");
    }
    if (strncmp(buf, "HTTP/1.1 200", 12))
        die("the server answered with an error");
    const char *cl = strcasestr(buf, "Content-Length:");
    if (!cl)
        die("reply without Content-Length");
    size_t body = strtoull(cl + 15, NULL, 10), head = (size_t)(end + 4 - buf);
    size_t have = got - head;
    if (body > have) {
        char *tmp = malloc(body - have);
        recv_all(fd, tmp, body - have);
        free(tmp);
    }
}

/* ---- runs -------------------------------------------------------------------------------- */

typedef struct shared {
    const options *o;
    request *requests;
    size_t count;
    atomic_size_t next;
    double *latency;
} shared;

static void *client(void *arg)
{
    shared *s = arg;
    int fd = connect_to(s->o->form == BINARY ? s->o->bin : s->o->http);
    for (size_t i; (i = atomic_fetch_add(&s->next, 1)) < s->count;) {
        double t0 = now();
        roundtrip(s->o, fd, &s->requests[i]);
        s->latency[i] = now() - t0;
    }
    close(fd);
    return NULL;
}

static int by_value(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static options parse(int argc, char **argv)
{
    options o = {.name = "demo", .workload = "band", .clients = 1, .repeat = 2, .per_request = 1000,
                 .n = 1000000, .seed = 7, .http = "127.0.0.1:8080", .bin = "127.0.0.1:9090"};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (a[0] != '-') {
            if (!o.mesh) o.mesh = a;
            else o.points = a;
            continue;
        }
        if (!v)
            die("every option takes a value");
        i++;
        if (!strcmp(a, "--http")) o.http = v;
        else if (!strcmp(a, "--bin")) o.bin = v;
        else if (!strcmp(a, "--name")) o.name = v;
        else if (!strcmp(a, "--workload")) o.workload = v;
        else if (!strcmp(a, "--n")) o.n = strtoull(v, NULL, 10);
        else if (!strcmp(a, "--seed")) o.seed = strtoull(v, NULL, 10);
        else if (!strcmp(a, "--clients")) o.clients = atoi(v);
        else if (!strcmp(a, "--per-request")) o.per_request = strtoull(v, NULL, 10);
        else if (!strcmp(a, "--repeat")) o.repeat = atoi(v);
        else if (!strcmp(a, "--form")) {
            o.form = !strcmp(v, "binary") ? BINARY : !strcmp(v, "octet") ? OCTET
                   : !strcmp(v, "json")  ? JSON : (die("--form binary|octet|json"), BINARY);
        } else die("unknown option (see the comment at the top of sdfd-bench.c)");
    }
    if (!o.mesh || o.clients < 1 || o.repeat < 1 || o.per_request < 1)
        die("usage: sdfd-bench MESH|demo [POINTS.npy] --http H:P --bin H:P [--form ...] [--clients C]");
    return o;
}

static float *load_points(const options *o, size_t *n)
{
    if (o->points) {
        size_t size;
        char *data = read_whole_file(o->points, &size);
        sdf_npy_info info;
        if (!data || sdf_npy_parse(data, size, &info, NULL) || info.dtype != SDF_NPY_F32 ||
            info.ndim != 2 || info.shape[1] != 3)
            die("POINTS.npy must be a float32 (N, 3) array");
        *n = info.shape[0];
        float *p = malloc(12 * *n + 4);
        memcpy(p, data + info.data_offset, 12 * *n);
        free(data);
        return p;
    }
    sdf_mesh *mesh;
    if (strcmp(o->mesh, "demo") ? sdf_mesh_load_file(o->mesh, NULL, &mesh, NULL)
                                : sdf_mesh_create_demo(&mesh))
        die("cannot load the mesh");
    *n = o->n;
    float *p = malloc(12 * *n + 4);
    if (sdf_workload(mesh, o->workload, n, o->seed, p))
        die("unknown workload");
    sdf_mesh_release(mesh);
    return p;
}

int main(int argc, char **argv)
{
    options o = parse(argc, argv);
    size_t n;
    float *points = load_points(&o, &n);
    static const char *const names[] = {"binary", "octet", "json"};
    if (o.clients == 1) { /* one request with every point */
        request r = encode(&o, points, n, 1);
        int fd = connect_to(o.form == BINARY ? o.bin : o.http);
        roundtrip(&o, fd, &r); /* warm-up */
        double best = 1e300;
        for (int i = 0; i < o.repeat; i++) {
            double t0 = now();
            roundtrip(&o, fd, &r);
            double t = now() - t0;
            best = t < best ? t : best;
        }
        close(fd);
        printf("points: %zu form: %s clients: 1 requests: 1 request_bytes: %zu\n", n, names[o.form], r.len);
        printf("seconds: %.4f\n", best);
        printf("throughput: %.4f Mq/s\n", (double)n / best / 1e6);
        return 0;
    }
    shared s = {.o = &o, .count = (n + o.per_request - 1) / o.per_request};
    s.requests = malloc(s.count * sizeof *s.requests);
    s.latency = malloc(s.count * sizeof *s.latency);
    for (size_t i = 0; i < s.count; i++) {
        size_t begin = i * o.per_request, k = n - begin < o.per_request ? n - begin : o.per_request;
        s.requests[i] = encode(&o, points + 3 * begin, k, (uint32_t)i + 1);
    }
    pthread_t *t = malloc((size_t)o.clients * sizeof *t);
    atomic_init(&s.next, 0);
    double t0 = now();
    for (int i = 0; i < o.clients; i++)
        pthread_create(&t[i], NULL, client, &s);
    for (int i = 0; i < o.clients; i++)
        pthread_join(t[i], NULL);
    double wall = now() - t0;
    qsort(s.latency, s.count, sizeof *s.latency, by_value);
    printf("points: %zu form: %s clients: %d requests: %zu points/request: %zu\n", n, names[o.form],
           o.clients, s.count, o.per_request);
    printf("latency ms: p50 %.3f p99 %.3f max %.3f\n", 1e3 * s.latency[s.count / 2],
           1e3 * s.latency[s.count * 99 / 100], 1e3 * s.latency[s.count - 1]);
    printf("seconds: %.4f\n", wall);
    printf("throughput: %.4f Mq/s\n", (double)n / wall / 1e6);
    return 0;
}
