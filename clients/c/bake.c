/* bake.c - the two commands that start a job: `sdfq bake` (POST the bake) and `sdfq ops`
 * (POST field operations on a volume), then with --wait poll the job until it ends, drawing
 * a bar on a terminal and writing a plain line at each tenth otherwise (a log or a CI run
 * then gets a few lines, not thousands of carriage returns). */
#include <cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "commands.h"
#include "http.h"

/* Field operations NAME=R, in order, added to `o` as "ops": [{"NAME": R}, ...] with the
 * options that go with them (solver, iterations, band, strict). The server judges the names
 * and the numbers' ranges; here only the shape. 0, or 1 after a message. */
static int add_ops(const sdfq_args *a, cJSON *o, const char *const *ops, int n)
{
    long iterations = -1;
    double band = 0;
    if (sdfq_opt_long(a, "iterations", 0, 1000000, &iterations) ||
        sdfq_opt_double(a, "band", &band))
        return 1;
    cJSON *list = n ? cJSON_AddArrayToObject(o, "ops") : NULL;
    for (int i = 0; i < n; i++) {
        const char *eq = strchr(ops[i], '=');
        char *end = NULL;
        errno = 0;
        double r = eq ? strtod(eq + 1, &end) : 0;
        if (!eq || eq == ops[i] || eq - ops[i] > 32 || end == eq + 1 || *end || errno ||
            !isfinite(r)) {
            fprintf(stderr, "sdfq %s: an operation is NAME=R (round=0.05, fillet=0.05, "
                    "smooth=0.05, offset=-0.1, redistance=0.15), not '%s'\n", a->cmd, ops[i]);
            return 1;
        }
        char name[33];
        snprintf(name, sizeof name, "%.*s", (int)(eq - ops[i]), ops[i]);
        cJSON *op = cJSON_CreateObject();
        cJSON_AddNumberToObject(op, name, r);
        cJSON_AddItemToArray(list, op);
    }
    if (sdfq_opt_value(a, "solver"))
        cJSON_AddStringToObject(o, "solver", sdfq_opt_value(a, "solver"));
    if (iterations >= 0)
        cJSON_AddNumberToObject(o, "iterations", (double)iterations);
    if (sdfq_opt_value(a, "band"))
        cJSON_AddNumberToObject(o, "band", band);
    if (sdfq_opt_value(a, "strict"))
        cJSON_AddTrueToObject(o, "strict");
    return 0;
}

/* The bake's JSON body from the options; NULL after a message. */
static char *bake_body(const sdfq_args *a)
{
    long resolution = 0, order = -1;
    double margin = -1;
    if (sdfq_opt_long(a, "resolution", 2, 4096, &resolution) ||
        sdfq_opt_long(a, "order", 0, 1, &order) || sdfq_opt_double(a, "margin", &margin))
        return NULL;
    cJSON *o = cJSON_CreateObject();
    const sdfq_opt *op = sdfq_opt_find(a, "op");
    if (add_ops(a, o, op->values, op->count)) {
        cJSON_Delete(o);
        return NULL;
    }
    const char *text[] = {"volume", "encoding", "sign", "normalize"};
    for (size_t i = 0; i < sizeof text / sizeof *text; i++)
        if (sdfq_opt_value(a, text[i]))
            cJSON_AddStringToObject(o, text[i], sdfq_opt_value(a, text[i]));
    if (resolution)
        cJSON_AddNumberToObject(o, "resolution", (double)resolution);
    if (order >= 0)
        cJSON_AddNumberToObject(o, "order", (double)order);
    if (margin >= 0)
        cJSON_AddNumberToObject(o, "margin", margin);
    char *body = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return body;
}

static void sleep_ms(long ms)
{
    struct timespec t = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&t, NULL);
}

/* A terminal gets one redrawn bar; a pipe gets a line at each tenth of the progress and at
 * each change of state, so the last line always says how the job ended. `kind` is the
 * command: bake or ops. */
static void show(int tty, const char *kind, const char *volume, const char *state,
                 double percent, int *last, char last_state[16])
{
    if (tty) {
        int filled = (int)(percent / 5);
        fprintf(stderr, "\r%s %s [%.*s%*s] %5.1f%% %-8s", kind, volume, filled,
                "####################", 20 - filled, "", percent, state);
        fflush(stderr);
    } else if ((int)(percent / 10) != *last || strncmp(state, last_state, 15)) {
        *last = (int)(percent / 10);
        snprintf(last_state, 16, "%s", state);
        fprintf(stderr, "%s %s: %s %.0f%%\n", kind, volume, state, percent);
    }
}

/* Poll job `id` until it ends: 0 (done, its final JSON printed, and its field operations'
 * warning, if any, on stderr), or an exit code. */
static int wait_job(const sdfq_server *srv, const char *kind, const char *id, const char *volume)
{
    char path[128];
    snprintf(path, sizeof path, "/v1/jobs/%.100s", id);
    int tty = isatty(STDERR_FILENO), last = -1;
    char last_state[16] = "";
    for (;;) {
        sdfq_request req = {.method = "GET", .path = path};
        sdfq_reply reply;
        int rc = sdfq_http(srv, &req, &reply);
        if (rc)
            return rc;
        cJSON *job = cJSON_ParseWithLength(reply.body ? reply.body : "", reply.len);
        const char *state = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(job, "state"));
        double percent = cJSON_GetNumberValue(cJSON_GetObjectItemCaseSensitive(job, "percent"));
        if (!state) {
            fprintf(stderr, "sdfq: %s%s: not the job JSON the API documents\n", srv->url, path);
            rc = SDFQ_CONNECT;
        } else {
            show(tty, kind, volume, state, percent == percent ? percent : 0, &last, last_state);
        }
        int end = state && (!strcmp(state, "done") || !strcmp(state, "failed") ||
                            !strcmp(state, "canceled"));
        if (end && tty)
            fputc('\n', stderr);
        if (end && !strcmp(state, "done")) {
            const char *warning =
                cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(job, "warning"));
            if (warning && *warning)
                fprintf(stderr, "%s %s: warning: %s\n", kind, volume, warning);
            printf("%s\n", reply.body);
        } else if (end) {
            cJSON *e = cJSON_GetObjectItemCaseSensitive(job, "error");
            const char *code = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(e, "code"));
            const char *msg = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(e, "message"));
            fprintf(stderr, "sdfq: server: %s %s %s: %s: %s\n", kind, id, state,
                    code ? code : "ECANCELED", msg ? msg : "the job was canceled");
            rc = SDFQ_REFUSED;
        }
        cJSON_Delete(job);
        sdfq_reply_free(&reply);
        if (rc || end)
            return rc;
        sleep_ms(100);
    }
}

/* POST `body` to /v1/{collection}/{name}/{action}, which answers 202 with a job; then print
 * the job's id, or with --wait follow it to its end. */
static int start_job(const sdfq_server *srv, const sdfq_args *a, const char *collection,
                     const char *action, char *body)
{
    char *name = sdfq_escape(a->pos[0]);
    char path[800];
    snprintf(path, sizeof path, "/v1/%s/%s/%s", collection, name ? name : "", action);
    free(name);
    sdfq_request req = {.method = "POST", .path = path, .body = body, .body_len = strlen(body),
                        .content_type = "application/json"};
    sdfq_reply reply;
    int rc = sdfq_http(srv, &req, &reply);
    free(body);
    if (rc)
        return rc;
    cJSON *job = cJSON_ParseWithLength(reply.body ? reply.body : "", reply.len);
    const char *id = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(job, "id"));
    const char *vol = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(job, "volume"));
    if (!id) {
        fprintf(stderr, "sdfq: the %s's answer has no job id\n", a->cmd);
        rc = SDFQ_CONNECT;
    } else if (sdfq_opt_value(a, "wait")) {
        rc = wait_job(srv, a->cmd, id, vol ? vol : a->pos[0]);
    } else {
        printf("%s\n", id);
    }
    cJSON_Delete(job);
    sdfq_reply_free(&reply);
    return rc;
}

int sdfq_cmd_bake(const sdfq_server *srv, const sdfq_args *a)
{
    if (a->npos != 1) {
        fprintf(stderr, "sdfq bake: needs one mesh name (see sdfq bake --help)\n");
        return SDFQ_USAGE;
    }
    char *body = bake_body(a);
    return body ? start_job(srv, a, "meshes", "bake", body) : SDFQ_USAGE;
}

int sdfq_cmd_ops(const sdfq_server *srv, const sdfq_args *a)
{
    if (a->npos < 2) {
        fprintf(stderr, "sdfq ops: needs a volume name and at least one operation (see sdfq "
                "ops --help)\n");
        return SDFQ_USAGE;
    }
    cJSON *o = cJSON_CreateObject();
    if (sdfq_opt_value(a, "volume"))
        cJSON_AddStringToObject(o, "volume", sdfq_opt_value(a, "volume"));
    int bad = add_ops(a, o, a->pos + 1, a->npos - 1);
    char *body = bad ? NULL : cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return body ? start_job(srv, a, "volumes", "ops", body) : SDFQ_USAGE;
}
