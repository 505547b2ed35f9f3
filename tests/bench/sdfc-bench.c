/* sdfc-bench - the C client's (libsdfclient) throughput on one request of every point, for
 * tests/bench/server-compare.sh, next to the in-process library on the same points. Not a
 * test: it asserts nothing but that the server answered.
 *
 *   sdfc-bench POINTS.npy --bin HOST:PORT [--name NAME] [--repeat R] [--out OUT.f32]
 *
 * POINTS.npy is (N, 3) float32 or float64 (sdf-bench --points-out writes it). One QUERY of
 * all N points, signed, sign auto, on mesh NAME (default demo) goes over one connection: once
 * untimed (a fresh server's first large buffers come from fresh pages), then R times (default
 * 2), best reported. Timed is what a program pays: sdfc_query from the points in memory to
 * the distances in its buffer. --out writes the distances as raw little-endian float32 (the
 * data of sdf-bench --out's .npy), to be compared byte for byte. Also printed: the client's
 * CPU time (this process's, user and system) per timed request, which the machine's other
 * work inflates far less than the wall time. The last line printed is `throughput: X Mq/s`. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../common/npyio.h"
#include "sdfclient.h"

typedef struct args {
    const char *points, *bin, *name, *out;
    int repeat;
} args;

static void usage(void)
{
    fprintf(stderr, "usage: sdfc-bench POINTS.npy --bin HOST:PORT [--name NAME] [--repeat R] "
                    "[--out OUT.f32]\n");
    exit(2);
}

static double clock_s(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static args parse_args(int argc, char **argv)
{
    args a = {.name = "demo", .repeat = 2};
    for (int i = 1; i < argc; i++) {
        const char *s = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (s[0] != '-') {
            if (a.points)
                usage();
            a.points = s;
            continue;
        }
        if (!v)
            usage();
        i++;
        if (!strcmp(s, "--bin")) a.bin = v;
        else if (!strcmp(s, "--name")) a.name = v;
        else if (!strcmp(s, "--out")) a.out = v;
        else if (!strcmp(s, "--repeat")) a.repeat = atoi(v);
        else usage();
    }
    if (!a.points || !a.bin || a.repeat < 1 || !strrchr(a.bin, ':'))
        usage();
    return a;
}

static void fail(const sdfc_client *c, const char *what, int rc)
{
    const sdfc_server_err *e = c ? sdfc_server_error(c) : NULL;
    fprintf(stderr, "sdfc-bench: %s: %s%s%s\n", what, sdfc_strerror(rc),
            e && e->code[0] ? " " : "", e && e->code[0] ? e->message : "");
    exit(1);
}

static void write_raw(const char *path, const float *dist, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(dist, 4, n, f) != n || fclose(f)) {
        fprintf(stderr, "sdfc-bench: cannot write %s\n", path);
        exit(1);
    }
}

int main(int argc, char **argv)
{
    args a = parse_args(argc, argv);
    size_t n;
    float *points = npy_load_points("sdfc-bench", a.points, &n);
    if (n > UINT32_MAX) {
        fprintf(stderr, "sdfc-bench: %zu points do not fit one request\n", n);
        return 1;
    }
    char host[256];
    const char *colon = strrchr(a.bin, ':');
    snprintf(host, sizeof host, "%.*s", (int)(colon - a.bin), a.bin);
    sdfc_client *c;
    int rc = sdfc_connect(host, atoi(colon + 1), NULL, &c);
    if (rc)
        fail(NULL, "cannot connect", rc);
    size_t size = sdfc_result_size(SDFC_SIGNED, (uint32_t)n);
    float *dist = malloc(size + 4);
    double best = 1e300, cpu = 0;
    for (int i = -1; i < a.repeat; i++) { /* i = -1: the untimed warm-up */
        double t0 = clock_s(CLOCK_MONOTONIC), c0 = clock_s(CLOCK_PROCESS_CPUTIME_ID);
        rc = sdfc_query(c, a.name, SDFC_SIGNED, SDFC_SIGN_AUTO, NULL, points, (uint32_t)n, dist,
                        size);
        double t = clock_s(CLOCK_MONOTONIC) - t0;
        if (rc)
            fail(c, "query", rc);
        if (i >= 0) {
            best = t < best ? t : best;
            cpu += clock_s(CLOCK_PROCESS_CPUTIME_ID) - c0;
        }
    }
    sdfc_close(c);
    if (a.out)
        write_raw(a.out, dist, n);
    printf("points: %zu client: libsdfclient form: binary requests: 1\n", n);
    printf("client cpu ms: %.1f\n", 1e3 * cpu / a.repeat);
    printf("seconds: %.4f\n", best);
    printf("throughput: %.4f Mq/s\n", (double)n / best / 1e6);
    free(points);
    free(dist);
    return 0;
}
