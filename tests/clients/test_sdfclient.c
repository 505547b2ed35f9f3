/* test_sdfclient.c - libsdfclient against a real sdfd and against a fake server.
 *
 * Real server (SDFC_TEST_BIN=host:port, demo mesh; SDFC_TEST_AUTH_BIN, one started with
 * --token s3cret --auth-queries; run_sdfclient.py starts both): HELLO, LIST_MESHES, every
 * mode; hundreds of pipelined queries of many sizes waited for in reverse order and in
 * arrival order give the same bits as the same queries sent one at a time; refusals keep the
 * server's status, code and message and leave the connection usable; AUTH right and wrong;
 * local refusals (small buffer, too many points, bad names) send nothing.
 * TLS (SDFC_TEST_TLS_BIN, a --bin-tls sdfd whose certificate the CA in SDFC_TEST_CA signed
 * for 127.0.0.1 and localhost; SDFC_TEST_ELSEWHERE_BIN, one whose certificate names another
 * host; SDFC_TEST_OTHER_CA, a CA that signed neither): the same bits as the plain port for
 * the same pipelined queries; another CA, another host name, a plain port, a CA file that
 * does not load are each refused with their own code; a silent server times the handshake
 * out.
 * Re-sending (through cutproxy.c, which cuts a connection after so many bytes as a dying
 * replica behind a load balancer would): the answers arrive, bit-equal, over one new
 * connection with the token sent again, over plain and TLS, cut while receiving and while
 * sending; a second cut of a re-sent request is the error; without `resend` the first is.
 * A query the proxy refuses as a draining sdfd would (503 EUNAVAILABLE) goes again once on
 * a new connection, after the replies on the old one; a second refusal, or one without
 * `resend`, is the caller's. A connection the proxy resets as soon as it accepts it is
 * replaced (sdfc_connect's AUTH, a replacement's handshake: three attempts in all).
 * Fake server (a listening socket in this process): the bytes the client sends, with the
 * points passed straight from the caller's array, are exactly the codec's
 * sdf_proto_encode_query frame (the differential test of that fast path), and each
 * interpolation name's VOLUME_QUERY the codec's frame for the library's filter of that name;
 * malformed replies
 * are EPROTO and sticky; silence is ETIMEDOUT; a connection-level ERROR is kept. */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "../common/check.h"
#include "cutproxy.h"
#include "proto.h"
#include "sdfclient.h"

static char host[64];
static int port, auth_port, tls_port, elsewhere_port;
static const char *ca_file, *other_ca_file;

static int parse_addr(const char *env, int *out)
{
    const char *s = getenv(env);
    const char *colon = s ? strrchr(s, ':') : NULL;
    if (!colon || colon - s >= (int)sizeof host)
        return -1;
    memcpy(host, s, (size_t)(colon - s));
    host[colon - s] = 0;
    *out = atoi(colon + 1);
    return 0;
}

static sdfc_client *open_client(int p, const char *token)
{
    sdfc_options o = {.reply_timeout_ms = 60000, .token = token};
    sdfc_client *c = NULL;
    int rc = sdfc_connect(host, p, &o, &c);
    CHECK(rc == 0 && c, "connect %s:%d: %s", host, p, sdfc_strerror(rc));
    return c;
}

static float *random_points(size_t n, unsigned seed)
{
    float *p = malloc(12 * (n ? n : 1));
    srand(seed);
    for (size_t i = 0; i < 3 * n; i++)
        p[i] = (float)rand() / (float)RAND_MAX * 3.0f - 1.5f;
    return p;
}

static void test_hello_and_meshes(sdfc_client *c)
{
    sdfc_hello_info h;
    CHECK(sdfc_hello(c, &h) == 0 && h.version == 1 && h.max_points > 0 &&
              h.max_payload > 12 * (uint64_t)h.max_points && h.server[0],
          "hello: version %d, max_points %u", h.version, h.max_points);
    size_t count = 0;
    CHECK(sdfc_list_meshes(c, NULL, 0, &count) == 0 && count >= 1, "mesh count %zu", count);
    sdfc_mesh m[4];
    CHECK(sdfc_list_meshes(c, m, 4, &count) == 0 && !strcmp(m[0].name, "demo") &&
              m[0].triangles > 0 && m[0].closed == 1,
          "demo listed: %s %llu", m[0].name, (unsigned long long)m[0].triangles);
}

/* Pipelined queries equal the same queries one at a time, bit for bit. */
static void test_pipelining(sdfc_client *c)
{
    enum { N = 300 };
    static uint32_t ids[N];
    static void *piped[N], *single[N];
    static uint32_t counts[N];
    float *pts[N];
    sdfc_mode modes[N];
    for (int i = 0; i < N; i++) {
        counts[i] = (uint32_t)(i % 7 == 0 ? 0 : (i * 37) % 500 + 1);
        modes[i] = (sdfc_mode)(i % 4); /* signed, distance, gradient, closest */
        pts[i] = random_points(counts[i], (unsigned)i + 1);
        size_t size = sdfc_result_size(modes[i], counts[i]);
        piped[i] = calloc(1, size + 1);
        single[i] = calloc(1, size + 1);
        int rc = sdfc_send_query(c, "demo", modes[i], SDFC_SIGN_AUTO, NULL, pts[i], counts[i],
                                 piped[i], size, &ids[i]);
        CHECK(rc == 0, "send %d: %s", i, sdfc_strerror(rc));
    }
    CHECK(sdfc_in_flight(c) == N, "in flight %zu", sdfc_in_flight(c));
    for (int i = N - 1; i >= N / 2; i--) /* half in reverse order */
        CHECK(sdfc_wait(c, ids[i]) == 0, "wait %d", i);
    for (int left = N / 2; left > 0; left--) { /* the rest as they come */
        uint32_t id;
        CHECK(sdfc_wait_any(c, &id) == 0 && id >= ids[0] && id < ids[0] + N / 2, "any %u", id);
    }
    uint32_t none;
    CHECK(sdfc_wait_any(c, &none) == SDFC_ENOREQUEST && sdfc_wait(c, ids[0]) == SDFC_ENOREQUEST,
          "nothing left in flight");
    for (int i = 0; i < N; i++) {
        size_t size = sdfc_result_size(modes[i], counts[i]);
        int rc = sdfc_query(c, "demo", modes[i], SDFC_SIGN_AUTO, NULL, pts[i], counts[i],
                            single[i], size);
        CHECK(rc == 0 && !memcmp(piped[i], single[i], size + 1), "request %d (%u points, %s)",
              i, counts[i], sdf_proto_mode_name((sdf_proto_mode)modes[i]));
        free(pts[i]);
        free(piped[i]);
        free(single[i]);
    }
}

static void test_filtered(sdfc_client *c)
{
    float *p = random_points(50, 99);
    float a[200], b[200];
    sdfc_filter f = {.samples = 16, .seed = 3};
    CHECK(sdfc_query(c, "demo", SDFC_FILTERED_GRADIENT, SDFC_SIGN_AUTO, &f, p, 50, a, sizeof a) == 0,
          "filtered-gradient");
    CHECK(sdfc_query(c, "demo", SDFC_FILTERED_GRADIENT, SDFC_SIGN_AUTO, &f, p, 50, b, sizeof b) == 0 &&
              !memcmp(a, b, sizeof a),
          "the same seed gives the same bits");
    f.samples = 5000;
    CHECK(sdfc_query(c, "demo", SDFC_FILTERED, SDFC_SIGN_AUTO, &f, p, 50, a, sizeof a) ==
                  SDFC_ESERVER &&
              sdfc_server_error(c)->status == 422,
          "too many samples: %s", sdfc_server_error(c)->message);
    f.flags = 0x100;
    CHECK(sdfc_query(c, "demo", SDFC_FILTERED, SDFC_SIGN_AUTO, &f, p, 50, a, sizeof a) == SDFC_EINVAL,
          "unknown filter flag refused locally");
    free(p);
}

static void test_refusals(sdfc_client *c)
{
    float p[6] = {0, 0, 0, 1, 1, 1}, out[10];
    CHECK(sdfc_query(c, "nope", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 2, out, sizeof out) ==
              SDFC_ESERVER,
          "unknown mesh");
    const sdfc_server_err *e = sdfc_server_error(c);
    CHECK(e->status == 404 && !strcmp(e->code, "ENOTFOUND") && strstr(e->message, "nope"),
          "kept: %d %s %s", e->status, e->code, e->message);
    p[4] = 0.0f / 0.0f;
    CHECK(sdfc_query(c, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 2, out, sizeof out) ==
              SDFC_ESERVER && !strcmp(sdfc_server_error(c)->code, "ENONFINITE"),
          "NaN point");
    p[4] = 1;
    CHECK(sdfc_query(c, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 2, out, sizeof out) == 0 &&
              sdfc_server_error(c)->code[0] == 0,
          "the connection goes on after refusals; the error is cleared");
    CHECK(sdfc_query(c, "demo", SDFC_GRADIENT, SDFC_SIGN_AUTO, NULL, p, 2, out, 31) == SDFC_ELIMIT,
          "small buffer");
    sdfc_hello_info h;
    sdfc_hello(c, &h);
    CHECK(sdfc_query(c, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, h.max_points + 1, out,
                     SIZE_MAX) == SDFC_ELIMIT,
          "more than max_points");
    char long_name[300];
    memset(long_name, 'a', 299);
    long_name[299] = 0;
    CHECK(sdfc_query(c, long_name, SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 2, out, sizeof out) ==
                  SDFC_EINVAL &&
              sdfc_query(c, "", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 2, out, sizeof out) == SDFC_EINVAL &&
              sdfc_query(c, "demo", (sdfc_mode)9, SDFC_SIGN_AUTO, NULL, p, 2, out, sizeof out) ==
                  SDFC_EINVAL,
          "bad names and modes");
    CHECK(sdfc_in_flight(c) == 0 &&
              sdfc_query(c, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 2, out, sizeof out) == 0,
          "local refusals sent nothing");
}

static void test_auth(void)
{
    float p[3] = {0, 0, 0}, out[1];
    sdfc_client *c = open_client(auth_port, NULL);
    size_t count;
    CHECK(c && sdfc_list_meshes(c, NULL, 0, &count) == 0, "mesh list needs no token");
    CHECK(c && sdfc_query(c, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 1, out, 4) == SDFC_ESERVER &&
              !strcmp(sdfc_server_error(c)->code, "EUNAUTHORIZED"),
          "query without AUTH");
    CHECK(c && sdfc_auth(c, "wrong", 5) == SDFC_ESERVER &&
              sdfc_server_error(c)->status == 401,
          "wrong token");
    CHECK(c && sdfc_query(c, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 1, out, 4) == SDFC_ECLOSED,
          "closed after a wrong token");
    sdfc_close(c);
    c = open_client(auth_port, "s3cret");
    CHECK(c && sdfc_query(c, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 1, out, 4) == 0,
          "right token");
    sdfc_close(c);
    sdfc_client *bad = (sdfc_client *)1;
    sdfc_options o = {.token = "nope"};
    CHECK(sdfc_connect(host, auth_port, &o, &bad) == SDFC_ESERVER && bad == NULL,
          "connect with a wrong token");
}

/* ---- TLS --------------------------------------------------------------------------------- */

static int connect_tls(const char *h, int p, const char *ca, sdfc_client **out)
{
    sdfc_options o = {.reply_timeout_ms = 60000, .tls = 1, .ca_file = ca};
    return sdfc_connect(h, p, &o, out);
}

/* The same pipelined queries (every mode, up to 100,000 points: replies of many TLS records
 * and more than a socket buffer) on two handles give the same bits. */
static void same_bits(sdfc_client *a, sdfc_client *b, const char *what)
{
    enum { N = 24 };
    uint32_t counts[N], ida[N], idb[N];
    sdfc_mode modes[N];
    float *pts[N];
    unsigned char *ra[N], *rb[N];
    for (int i = 0; i < N; i++) {
        counts[i] = i % 6 == 5 ? 100000 : (uint32_t)(i * 97 % 3000);
        modes[i] = (sdfc_mode)(i % 4);
        pts[i] = random_points(counts[i], 500u + (unsigned)i);
        size_t size = sdfc_result_size(modes[i], counts[i]);
        ra[i] = calloc(1, size + 1);
        rb[i] = calloc(1, size + 1);
        CHECK(sdfc_send_query(a, "demo", modes[i], SDFC_SIGN_AUTO, NULL, pts[i], counts[i], ra[i],
                              size, &ida[i]) == 0 &&
                  sdfc_send_query(b, "demo", modes[i], SDFC_SIGN_AUTO, NULL, pts[i], counts[i],
                                  rb[i], size, &idb[i]) == 0,
              "%s: send %d", what, i);
    }
    for (int i = 0; i < N; i++) {
        size_t size = sdfc_result_size(modes[i], counts[i]);
        int r1 = sdfc_wait(a, ida[i]), r2 = sdfc_wait(b, idb[i]);
        CHECK(r1 == 0 && r2 == 0 && !memcmp(ra[i], rb[i], size), "%s: request %d (%u points): "
              "%s, %s", what, i, counts[i], sdfc_strerror(r1), sdfc_strerror(r2));
        free(pts[i]);
        free(ra[i]);
        free(rb[i]);
    }
}

static void test_tls(void)
{
    sdfc_client *t = NULL, *plain = open_client(port, NULL);
    int rc = connect_tls(host, tls_port, ca_file, &t);
    CHECK(rc == 0 && t, "TLS connect: %s", sdfc_strerror(rc));
    if (t) {
        test_hello_and_meshes(t);
        same_bits(t, plain, "TLS vs plain");
        sdfc_close(t);
    }
    sdfc_close(plain);
    rc = connect_tls("localhost", tls_port, ca_file, &t);
    CHECK(rc == 0 && sdfc_hello(t, &(sdfc_hello_info){0}) == 0,
          "by host name (SNI, a DNS name in the certificate): %s", sdfc_strerror(rc));
    sdfc_close(t);

    t = (sdfc_client *)1;
    rc = connect_tls(host, tls_port, other_ca_file, &t);
    CHECK(rc == SDFC_ECERT && t == NULL, "another CA: %s", sdfc_strerror(rc));
    rc = connect_tls(host, elsewhere_port, ca_file, &t);
    CHECK(rc == SDFC_ECERT && t == NULL, "a certificate for another host: %s", sdfc_strerror(rc));
    rc = connect_tls(host, port, ca_file, &t);
    CHECK(rc == SDFC_ETLS && t == NULL, "TLS to a plain port: %s", sdfc_strerror(rc));
    rc = connect_tls(host, tls_port, "/nonexistent/ca.pem", &t);
    CHECK(rc == SDFC_EINVAL && t == NULL, "a missing CA file: %s", sdfc_strerror(rc));
    char junk[] = "/tmp/sdfclient-junk-XXXXXX";
    int fd = mkstemp(junk);
    CHECK(fd >= 0 && write(fd, "not a certificate\n", 18) == 18, "junk file");
    close(fd);
    rc = connect_tls(host, tls_port, junk, &t);
    CHECK(rc == SDFC_EINVAL && t == NULL, "a CA file with no certificate: %s", sdfc_strerror(rc));
    unlink(junk);
    sdfc_options o = {.ca_file = ca_file};
    CHECK(sdfc_connect(host, tls_port, &o, &t) == SDFC_EINVAL, "ca_file without tls");

    /* plain frames to the TLS port: its handshake fails and it closes the connection */
    float p[3] = {0, 0, 0}, out[1];
    t = open_client(tls_port, NULL);
    rc = t ? sdfc_query(t, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 1, out, 4) : 0;
    CHECK(rc == SDFC_ECLOSED || rc == SDFC_EPROTO, "plain frames to a TLS port: %s",
          sdfc_strerror(rc));
    sdfc_close(t);
}

/* ---- re-sending on a lost connection ----------------------------------------------------- */

/* Send `n` queries of `count` points each (signed, from pts), wait for them in order; the
 * first error, or 0. */
static int ask(sdfc_client *c, const float *pts, int n, uint32_t count, float *out)
{
    uint32_t ids[16];
    int rc = 0;
    for (int i = 0; i < n && !rc; i++)
        rc = sdfc_send_query(c, "demo", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, pts + 3 * (size_t)count * i,
                             count, out + (size_t)count * i, 4 * (size_t)count, &ids[i]);
    for (int i = 0; i < n && !rc; i++)
        rc = sdfc_wait(c, ids[i]);
    return rc;
}

typedef struct resend_case {
    const char *what;
    int upstream;        /* the server's port */
    int tls;
    const char *token;
    int resend;
    cut_plan plan[3];    /* a third entry all zero: two (a zero plan cuts at once) */
    int n;               /* requests ... */
    uint32_t count;      /* ... of so many points */
    int want_rc;
    uint64_t connects, resent_min, resent_max;
} resend_case;

static void run_resend(const resend_case *k)
{
    size_t total = (size_t)k->n * k->count;
    float *pts = random_points(total, 41), *ref = malloc(4 * total), *got = calloc(total, 4);
    sdfc_client *direct = open_client(port, NULL);
    CHECK(ask(direct, pts, k->n, k->count, ref) == 0, "%s: direct answers", k->what);
    sdfc_close(direct);
    cut_proxy px;
    const cut_plan *third = &k->plan[2];
    int nplan = third->reply_bytes || third->request_bytes || third->accept_reset ||
                third->unavailable ? 3 : 2;
    CHECK(cut_proxy_start(&px, k->upstream, k->plan, nplan) == 0, "%s: proxy", k->what);
    sdfc_options o = {.reply_timeout_ms = 60000, .token = k->token, .tls = k->tls,
                      .ca_file = k->tls ? ca_file : NULL, .resend = k->resend};
    sdfc_client *c = NULL;
    int rc = sdfc_connect(host, px.port, &o, &c);
    CHECK(rc == 0, "%s: connect: %s", k->what, sdfc_strerror(rc));
    if (!rc) {
        rc = ask(c, pts, k->n, k->count, got);
        sdfc_stats st = {0};
        sdfc_get_stats(c, &st);
        CHECK(rc == k->want_rc, "%s: %s", k->what, sdfc_strerror(rc));
        CHECK(rc != SDFC_ESERVER || !strcmp(sdfc_server_error(c)->code, "EUNAVAILABLE"),
              "%s: the refusal is the proxy's: %s", k->what, sdfc_server_error(c)->code);
        CHECK(rc || !memcmp(got, ref, 4 * total), "%s: the answers are the direct bits", k->what);
        /* a TLS connection reset before its TLS handshake is never opened */
        uint64_t opened = k->connects;
        for (int i = 0; k->tls && i < (int)k->connects; i++)
            opened -= (uint64_t)k->plan[i < nplan ? i : nplan - 1].accept_reset;
        CHECK(st.connects == opened && st.resent >= k->resent_min &&
                  st.resent <= k->resent_max,
              "%s: %llu connections, %llu re-sent", k->what, (unsigned long long)st.connects,
              (unsigned long long)st.resent);
        CHECK(px.connections == (int)k->connects, "%s: the proxy saw %d", k->what,
              (int)px.connections);
        if (!rc && k->resend) { /* and the replacement goes on working */
            CHECK(ask(c, pts, 1, k->count, got) == 0 && !memcmp(got, ref, 4 * (size_t)k->count),
                  "%s: a query after", k->what);
        }
    }
    sdfc_close(c);
    cut_proxy_stop(&px);
    free(pts);
    free(ref);
    free(got);
}

static void test_resend(void)
{
    /* 5 x 100 points: a RESULT is 16 + 8 + 400 bytes; the cut lets two and a part through */
    const long R = 424, cut = 2 * R + 100;
#define CUT(replies, requests, reset) {(replies), (requests), (reset), 0, 0}
    const cut_plan pass = CUT(-1, -1, 0), first = CUT(cut, -1, 0);
    const cut_plan refuse = {-1, -1, 0, 0, 1}, reset_at_accept = {-1, -1, 0, 1, 0};
    resend_case cases[] = {
        {"once", port, 0, NULL, 1, {first, pass}, 5, 100, 0, 2, 3, 3},
        {"twice", port, 0, NULL, 1, {first, first}, 5, 100, SDFC_ECLOSED, 2, 3, 3},
        {"without resend", port, 0, NULL, 0, {first, pass}, 5, 100, SDFC_ECLOSED, 1, 0, 0},
        /* --auth-queries: a re-sent query without AUTH first would be refused */
        {"with a token", auth_port, 0, "s3cret", 1, {CUT(16 + cut, -1, 0), pass}, 5, 100, 0, 2,
         3, 3},
        /* a reset while sending 8 x 720 KB: the request cut in half goes again whole */
        {"reset while sending", port, 0, NULL, 1, {CUT(-1, 1 << 20, 1), pass}, 8, 60000, 0, 2,
         1, 8},
        {"TLS, closed while receiving", tls_port, 1, NULL, 1, {CUT(600000, -1, 0), pass}, 8,
         60000, 0, 2, 1, 7},
        {"TLS, reset while sending", tls_port, 1, NULL, 1, {CUT(-1, 1 << 20, 1), pass}, 8,
         60000, 0, 2, 1, 8},
        {"TLS, twice", tls_port, 1, NULL, 1, {CUT(600000, -1, 0), CUT(600000, -1, 1)}, 8, 60000,
         SDFC_ECLOSED, 2, 1, 7},
        /* a draining replica refuses the first query: it alone goes again, once, after the
         * other four are answered on the first connection */
        {"unavailable", port, 0, NULL, 1, {refuse, pass}, 5, 100, 0, 2, 1, 1},
        {"unavailable, with a token", auth_port, 0, "s3cret", 1, {refuse, pass}, 5, 100, 0, 2,
         1, 1},
        {"unavailable twice", port, 0, NULL, 1, {refuse, refuse}, 5, 100, SDFC_ESERVER, 2, 1, 1},
        {"unavailable without resend", port, 0, NULL, 0, {refuse, pass}, 5, 100, SDFC_ESERVER,
         1, 0, 0},
        /* a connection reset as soon as the balancer took it: sdfc_connect's AUTH, or the
         * first query, goes on a new one */
        {"reset at accept", port, 0, NULL, 1, {reset_at_accept, pass}, 5, 100, 0, 2, 1, 5},
        {"reset at accept, with a token", auth_port, 0, "s3cret", 1, {reset_at_accept, pass}, 5,
         100, 0, 2, 0, 0},
        /* the replacement's handshake is tried again, three times in all */
        {"a replacement reset at accept", port, 0, NULL, 1, {first, reset_at_accept, pass}, 5,
         100, 0, 3, 3, 3},
        {"TLS, a replacement reset at accept", tls_port, 1, NULL, 1,
         {CUT(600000, -1, 0), reset_at_accept, pass}, 8, 60000, 0, 3, 1, 7},
        {"every replacement reset at accept", port, 0, NULL, 1, {first, reset_at_accept}, 5, 100,
         SDFC_ECLOSED, 4, 0, 0},
    };
#undef CUT
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        run_resend(&cases[i]);
}

/* ---- the fake server --------------------------------------------------------------------- */

static int listen_loopback(int *port_out)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof a;
    if (fd < 0 || bind(fd, (struct sockaddr *)&a, sizeof a) || listen(fd, 4) ||
        getsockname(fd, (struct sockaddr *)&a, &len))
        return -1;
    *port_out = ntohs(a.sin_port);
    return fd;
}

static int read_n(int fd, unsigned char *buf, size_t n)
{
    for (size_t got = 0; got < n;) {
        ssize_t r = recv(fd, buf + got, n - got, 0);
        if (r <= 0)
            return -1;
        got += (size_t)r;
    }
    return 0;
}

/* A client on the fake server: *peer is the server's end. */
static sdfc_client *fake_pair(int lfd, int fport, int timeout_ms, int *peer)
{
    sdfc_options o = {.reply_timeout_ms = timeout_ms};
    sdfc_client *c = NULL;
    CHECK(sdfc_connect("127.0.0.1", fport, &o, &c) == 0, "connect to the fake server");
    *peer = accept(lfd, NULL, NULL);
    return c;
}

static void test_fake_server(void)
{
    int fport = 0, peer = -1, lfd = listen_loopback(&fport);
    CHECK(lfd >= 0, "listen");
    static unsigned char want[1 << 16], got[1 << 16];
    float *p = random_points(1000, 7);
    float out[5000];
    sdfc_filter f = {.kernel = 1, .flags = SDFC_FILTER_GRID, .samples = 9, .seed = 77,
                     .smooth = SDFC_SMOOTH_MESH, .smooth_mesh = "vol", .depth = 0.5};

    /* the frames on the wire are the codec's, byte for byte */
    sdfc_client *c = fake_pair(lfd, fport, 2000, &peer);
    uint32_t id, id2;
    CHECK(sdfc_send_query(c, "fandisk", SDFC_FILTERED, SDFC_SIGN_WINDING, &f, p, 1000, out,
                          sizeof out, &id) == 0, "send filtered");
    CHECK(sdfc_send_volume_query(c, "knot", 1, SDFC_INTERP_NEAREST, p, 999, out, sizeof out,
                                 &id2) == 0, "send vq");
    sdf_proto_query q = {.mode = SDF_MODE_FILTERED, .sign = SDF_SIGN_WINDING, .name = "fandisk",
                         .name_len = 7, .count = 1000, .points = p, .volume_name = "vol",
                         .volume_name_len = 3};
    q.filter = (sdf_filter_options){.kernel = SDF_KERNEL_BUMP, .grid = 1, .samples = 9, .seed = 77};
    q.filter.smooth.shape = SDF_VOLUME_MESH;
    q.filter.smooth.depth = 0.5;
    size_t n = sdf_proto_encode_query(want, sizeof want, id, &q);
    CHECK(n > 12000 && read_n(peer, got, n) == 0 && !memcmp(got, want, n), "QUERY frame bytes");
    sdf_proto_volume_query vq = {.gradient = 1, .interpolation = SDF_VOLUME_NEAREST,
                                 .name = "knot", .name_len = 4, .count = 999, .points = p};
    n = sdf_proto_encode_volume_query(want, sizeof want, id2, &vq);
    CHECK(n > 0 && read_n(peer, got, n) == 0 && !memcmp(got, want, n), "VOLUME_QUERY frame bytes");
    /* each interpolation by name is the codec's frame for the library's filter of that name */
    static const struct {
        const char *name;
        sdf_volume_filter filter;
    } interps[] = {{"trilinear", SDF_VOLUME_TRILINEAR}, {"nearest", SDF_VOLUME_NEAREST},
                   {"hermite", SDF_VOLUME_HERMITE}, {"default", SDF_VOLUME_DEFAULT}};
    static float vout[4][5]; /* never answered: the connection breaks first */
    for (size_t i = 0; i < sizeof interps / sizeof interps[0]; i++) {
        sdfc_interpolation it;
        uint32_t id3;
        CHECK(sdfc_interpolation_from_name(interps[i].name, &it) == 0, "%s", interps[i].name);
        CHECK(sdfc_send_volume_query(c, "knot", 0, it, p, 5, vout[i], sizeof vout[i], &id3) == 0,
              "send %s", interps[i].name);
        vq = (sdf_proto_volume_query){.interpolation = interps[i].filter, .name = "knot",
                                      .name_len = 4, .count = 5, .points = p};
        n = sdf_proto_encode_volume_query(want, sizeof want, id3, &vq);
        CHECK(n > 0 && read_n(peer, got, n) == 0 && !memcmp(got, want, n), "%s frame bytes",
              interps[i].name);
    }
    sdfc_interpolation it;
    CHECK(sdfc_interpolation_from_name("cubic", &it) == SDFC_EINVAL &&
              sdfc_interpolation_from_name(NULL, &it) == SDFC_EINVAL,
          "unknown interpolation names");
    size_t before = sdfc_in_flight(c);
    uint32_t unsent;
    CHECK(sdfc_send_volume_query(c, "knot", 0, (sdfc_interpolation)4, p, 5, vout[0],
                                 sizeof vout[0], &unsent) == SDFC_EINVAL && sdfc_in_flight(c) == before,
          "an unknown interpolation is refused before sending");

    /* an ERROR for the second, then a RESULT for the first whose count is wrong */
    n = sdf_proto_encode_error(want, sizeof want, id2, 404, "ENOTFOUND", "no volume named 'knot'");
    CHECK(send(peer, want, n, 0) == (ssize_t)n, "send error");
    CHECK(sdfc_wait(c, id2) == SDFC_ESERVER && !strcmp(sdfc_server_error(c)->code, "ENOTFOUND") &&
              sdfc_server_error(c)->status == 404,
          "ERROR frame kept");
    n = sdf_proto_encode_result_head(want, id, SDF_MODE_FILTERED, 999);
    memset(want + n, 0, 4 * 999);
    CHECK(send(peer, want, n + 4 * 999, 0) > 0, "send result");
    CHECK(sdfc_wait(c, id) == SDFC_EPROTO, "a RESULT of the wrong length is EPROTO");
    CHECK(sdfc_hello(c, &(sdfc_hello_info){0}) == SDFC_EPROTO, "and sticky");
    sdfc_close(c);
    close(peer);

    /* silence: the reply timeout */
    c = fake_pair(lfd, fport, 200, &peer);
    CHECK(sdfc_send_query(c, "m", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 10, out, sizeof out, &id) == 0 &&
              sdfc_wait(c, id) == SDFC_ETIMEDOUT,
          "no reply: timed out");
    sdfc_close(c);
    close(peer);

    /* a connection-level ERROR (request id 0), then the close */
    c = fake_pair(lfd, fport, 2000, &peer);
    n = sdf_proto_encode_error(want, sizeof want, 0, 429, "EBUSY", "no room for this connection");
    CHECK(send(peer, want, n, 0) == (ssize_t)n, "send busy");
    close(peer);
    CHECK(sdfc_query(c, "m", SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, p, 10, out, sizeof out) ==
                  SDFC_ECLOSED &&
              !strcmp(sdfc_server_error(c)->code, "EBUSY") && sdfc_server_error(c)->status == 429,
          "connection-level ERROR kept: %s", sdfc_server_error(c)->code);
    sdfc_close(c);
    close(lfd);

    /* a TLS handshake that gets no answer: the connect timeout */
    lfd = listen_loopback(&fport);
    sdfc_options o = {.tls = 1, .ca_file = ca_file, .connect_timeout_ms = 300};
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int rc = sdfc_connect("127.0.0.1", fport, &o, &c);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double secs = (double)(t1.tv_sec - t0.tv_sec) + (double)(t1.tv_nsec - t0.tv_nsec) / 1e9;
    CHECK(rc == SDFC_ETIMEDOUT && c == NULL && secs >= 0.25 && secs < 5,
          "silent TLS handshake: %s after %.2f s", sdfc_strerror(rc), secs);
    close(lfd);

    /* nobody listening */
    CHECK(sdfc_connect("127.0.0.1", fport, NULL, &c) == SDFC_ECONNECT && c == NULL, "refused");
    free(p);
}

/* The cases on one plain connection to the demo server, each its own. */
#define PLAIN_CASE(fn, test)                                                               \
    static void fn(void)                                                                   \
    {                                                                                      \
        sdfc_client *c = open_client(port, NULL);                                          \
        if (c)                                                                             \
            test(c);                                                                       \
        sdfc_close(c);                                                                     \
    }
PLAIN_CASE(case_hello_and_meshes, test_hello_and_meshes)
PLAIN_CASE(case_pipelining, test_pipelining)
PLAIN_CASE(case_filtered, test_filtered)
PLAIN_CASE(case_refusals, test_refusals)

static const check_case cases[] = {
    {"hello_and_meshes", case_hello_and_meshes},
    {"pipelining", case_pipelining},
    {"filtered", case_filtered},
    {"refusals", case_refusals},
    {"auth", test_auth},
    {"tls", test_tls},
    {"resend", test_resend},
    {"fake_server", test_fake_server},
};

int main(int argc, char **argv)
{
    int listing = argc == 2 && !strcmp(argv[1], "--list");
    ca_file = getenv("SDFC_TEST_CA");
    other_ca_file = getenv("SDFC_TEST_OTHER_CA");
    if (!listing && (parse_addr("SDFC_TEST_TLS_BIN", &tls_port) ||
                     parse_addr("SDFC_TEST_ELSEWHERE_BIN", &elsewhere_port) ||
                     parse_addr("SDFC_TEST_BIN", &port) ||
                     parse_addr("SDFC_TEST_AUTH_BIN", &auth_port) || !ca_file ||
                     !other_ca_file)) {
        fprintf(stderr, "test_sdfclient: set SDFC_TEST_BIN, SDFC_TEST_AUTH_BIN, "
                        "SDFC_TEST_TLS_BIN, SDFC_TEST_ELSEWHERE_BIN (host:port), SDFC_TEST_CA "
                        "and SDFC_TEST_OTHER_CA (tests/clients/run_sdfclient.py does)\n");
        return 1;
    }
    return check_main("sdfclient", cases, CHECK_COUNT_OF(cases), argc, argv);
}
