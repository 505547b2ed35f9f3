/* sdfc_load.c - libsdfclient's share of deploy/failover.py's binary load: one handle with
 * opts.resend (as sdfq has it) kept for the whole run, sending requests from a manifest one
 * or three at a time (pipelined) until a deadline, and comparing every answer bit for bit
 * with the reference's. A handle that breaks counts its unanswered requests as lost and is
 * replaced, as the Python workers replace theirs. Prints one JSON line of counts, which
 * failover.py judges: this program asserts nothing itself.
 *
 *   sdfc-load HOST PORT MANIFEST SECONDS SEED
 *
 * MANIFEST: one request a line, "KIND NAME MODE COUNT POINTS EXPECTED": KIND `meshes` or
 * `volumes`; MODE signed, distance, gradient, closest (meshes) or value, gradient (volumes);
 * POINTS a file of COUNT x 3 float32, EXPECTED one of the RESULT's words, little-endian. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sdfclient.h"

typedef struct request {
    char kind[16], name[256], mode[32];
    uint32_t count;
    float *points;
    void *expected, *got;
    size_t size;
} request;

typedef struct tally {
    long sent, ok, failed, mismatched;
    uint64_t connects, resent;
    double *done_at;
    size_t n_done, cap_done;
    char errors[5][640];
    int n_errors;
} tally;

static double now(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* The whole of `path`, which must be `size` bytes. */
static void *load(const char *path, size_t size)
{
    FILE *f = fopen(path, "rb");
    char *buf = malloc(size ? size : 1);
    size_t got = f && buf ? fread(buf, 1, size, f) : 0;
    int extra = f ? fgetc(f) : 0;
    if (f)
        fclose(f);
    if (got != size || extra != EOF) {
        fprintf(stderr, "sdfc-load: %s is not %zu bytes\n", path, size);
        exit(2);
    }
    return buf;
}

static request *read_manifest(const char *path, size_t *n)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "sdfc-load: cannot read %s\n", path);
        exit(2);
    }
    request *rs = NULL;
    char line[4096], pts[1024], exp[1024];
    for (*n = 0; fgets(line, sizeof line, f);) {
        request r = {0};
        sdfc_mode m = SDFC_SIGNED;
        if (sscanf(line, "%15s %255s %31s %u %1023s %1023s", r.kind, r.name, r.mode, &r.count,
                   pts, exp) != 6 ||
            r.count > 10000000 ||
            (strcmp(r.kind, "volumes") ? sdfc_mode_from_name(r.mode, &m) != 0
                                       : strcmp(r.mode, "value") && strcmp(r.mode, "gradient"))) {
            fprintf(stderr, "sdfc-load: bad manifest line: %s", line);
            exit(2);
        }
        int gradient = !strcmp(r.mode, "gradient");
        r.size = strcmp(r.kind, "volumes") ? sdfc_result_size(m, r.count)
                                           : (size_t)4 * (gradient ? 4 : 1) * r.count;
        r.points = load(pts, (size_t)12 * r.count);
        r.expected = load(exp, r.size);
        r.got = malloc(r.size ? r.size : 1);
        rs = realloc(rs, (*n + 1) * sizeof *rs);
        if (!rs || !r.got) {
            fprintf(stderr, "sdfc-load: out of memory\n");
            exit(2);
        }
        rs[(*n)++] = r;
    }
    fclose(f);
    if (*n == 0) {
        fprintf(stderr, "sdfc-load: %s holds no request\n", path);
        exit(2);
    }
    return rs;
}

static int send_one(sdfc_client *c, request *r, uint32_t *id)
{
    if (!strcmp(r->kind, "volumes"))
        return sdfc_send_volume_query(c, r->name, !strcmp(r->mode, "gradient"),
                                      SDFC_INTERP_DEFAULT, r->points, r->count, r->got, r->size, id);
    sdfc_mode m;
    sdfc_mode_from_name(r->mode, &m);
    return sdfc_send_query(c, r->name, m, SDFC_SIGN_AUTO, NULL, r->points, r->count, r->got,
                           r->size, id);
}

static void lost(tally *t, const request *r, sdfc_client *c, int rc)
{
    t->failed++;
    if (t->n_errors < 5) {
        const sdfc_server_err *e = sdfc_server_error(c);
        snprintf(t->errors[t->n_errors++], sizeof t->errors[0], "%s %s (%u points): %s %s",
                 r->name, r->mode, r->count, sdfc_strerror(rc), e ? e->code : "");
    }
}

static void answered(tally *t, const request *r)
{
    if (memcmp(r->got, r->expected, r->size)) {
        t->mismatched++;
        return;
    }
    t->ok++;
    if (t->n_done == t->cap_done) {
        t->cap_done = t->cap_done ? 2 * t->cap_done : 1024;
        if (!(t->done_at = realloc(t->done_at, t->cap_done * sizeof *t->done_at)))
            exit(2);
    }
    t->done_at[t->n_done++] = now(CLOCK_REALTIME);
}

/* One round: one request, or (a quarter of the rounds) three pipelined. 0, or the error
 * that broke the handle. */
static int round_trip(sdfc_client *c, request *rs, size_t n, tally *t)
{
    request *batch[3];
    uint32_t ids[3];
    int k = rand() % 4 == 0 ? 3 : 1, sent = 0, broken = 0;
    for (int i = 0; i < k; i++)
        batch[i] = &rs[(size_t)rand() % n];
    if (k == 3 && (batch[1] == batch[0] || batch[2] == batch[0] || batch[2] == batch[1]))
        k = 1; /* one buffer per request */
    for (; sent < k && !broken; sent++) {
        t->sent++;
        int rc = send_one(c, batch[sent], &ids[sent]);
        if (rc) {
            lost(t, batch[sent], c, rc);
            broken = rc != SDFC_ESERVER ? rc : 0;
            ids[sent] = 0;
        }
    }
    for (int i = 0; i < sent; i++) {
        if (!ids[i])
            continue;
        int rc = broken ? broken : sdfc_wait(c, ids[i]);
        if (rc) {
            lost(t, batch[i], c, rc);
            if (rc != SDFC_ESERVER)
                broken = rc;
        } else {
            answered(t, batch[i]);
        }
    }
    return broken;
}

static void print_json(const tally *t)
{
    printf("{\"sent\": %ld, \"ok\": %ld, \"failed\": %ld, \"mismatched\": %ld, \"connects\": %llu, "
           "\"resent\": %llu, \"errors\": [",
           t->sent, t->ok, t->failed, t->mismatched, (unsigned long long)t->connects,
           (unsigned long long)t->resent);
    for (int i = 0; i < t->n_errors; i++) {
        for (char *p = (char *)t->errors[i]; *p; p++)
            if (*p == '"' || *p == '\\' || (unsigned char)*p < 32)
                *p = '\'';
        printf("%s\"%s\"", i ? ", " : "", t->errors[i]);
    }
    printf("], \"done_at\": [");
    for (size_t i = 0; i < t->n_done; i++)
        printf("%s%.6f", i ? ", " : "", t->done_at[i]);
    printf("]}\n");
}

int main(int argc, char **argv)
{
    if (argc != 6) {
        fprintf(stderr, "usage: sdfc-load HOST PORT MANIFEST SECONDS SEED\n");
        return 2;
    }
    size_t n;
    request *rs = read_manifest(argv[3], &n);
    double deadline = now(CLOCK_MONOTONIC) + atof(argv[4]);
    srand((unsigned)atoi(argv[5]));
    sdfc_options o = {.reply_timeout_ms = 60000, .resend = 1};
    tally t = {0};
    sdfc_client *c = NULL;
    while (now(CLOCK_MONOTONIC) < deadline) {
        int rc = c ? 0 : sdfc_connect(argv[1], atoi(argv[2]), &o, &c);
        if (rc) {
            t.sent++;
            lost(&t, &rs[0], NULL, rc);
            nanosleep(&(struct timespec){.tv_nsec = 100000000}, NULL);
            continue;
        }
        if (round_trip(c, rs, n, &t)) {
            sdfc_stats st;
            sdfc_get_stats(c, &st);
            t.connects += st.connects;
            t.resent += st.resent;
            sdfc_close(c);
            c = NULL;
        }
    }
    if (c) {
        sdfc_stats st;
        sdfc_get_stats(c, &st);
        t.connects += st.connects;
        t.resent += st.resent;
        sdfc_close(c);
    }
    print_json(&t);
    for (size_t i = 0; i < n; i++) {
        free(rs[i].points);
        free(rs[i].expected);
        free(rs[i].got);
    }
    free(rs);
    free(t.done_at);
    return 0;
}
