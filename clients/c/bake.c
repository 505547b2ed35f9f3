/* bake.c - `sdfq bake`: POST the bake, then with --wait poll the job until it ends, drawing
 * a bar on a terminal and writing a plain line at each tenth otherwise (a log or a CI run
 * then gets a few lines, not thousands of carriage returns). */
#include <cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "commands.h"
#include "http.h"

/* The bake's JSON body from the options; NULL after a message. */
static char *bake_body(const sdfq_args *a)
{
    long resolution = 0, order = -1;
    double margin = -1;
    if (sdfq_opt_long(a, "resolution", 2, 4096, &resolution) ||
        sdfq_opt_long(a, "order", 0, 1, &order) || sdfq_opt_double(a, "margin", &margin))
        return NULL;
    cJSON *o = cJSON_CreateObject();
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
 * each change of state, so the last line always says how the job ended. */
static void show(int tty, const char *volume, const char *state, double percent, int *last,
                 char last_state[16])
{
    if (tty) {
        int filled = (int)(percent / 5);
        fprintf(stderr, "\rbake %s [%.*s%*s] %5.1f%% %-8s", volume, filled,
                "####################", 20 - filled, "", percent, state);
        fflush(stderr);
    } else if ((int)(percent / 10) != *last || strncmp(state, last_state, 15)) {
        *last = (int)(percent / 10);
        snprintf(last_state, 16, "%s", state);
        fprintf(stderr, "bake %s: %s %.0f%%\n", volume, state, percent);
    }
}

/* Poll job `id` until it ends: 0 (done, its final JSON printed), or an exit code. */
static int wait_job(const sdfq_server *srv, const char *id, const char *volume)
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
            show(tty, volume, state, percent == percent ? percent : 0, &last, last_state);
        }
        int end = state && (!strcmp(state, "done") || !strcmp(state, "failed") ||
                            !strcmp(state, "canceled"));
        if (end && tty)
            fputc('\n', stderr);
        if (end && !strcmp(state, "done")) {
            printf("%s\n", reply.body);
        } else if (end) {
            cJSON *e = cJSON_GetObjectItemCaseSensitive(job, "error");
            const char *code = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(e, "code"));
            const char *msg = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(e, "message"));
            fprintf(stderr, "sdfq: server: bake %s %s: %s: %s\n", id, state,
                    code ? code : "ECANCELED", msg ? msg : "the bake was canceled");
            rc = SDFQ_REFUSED;
        }
        cJSON_Delete(job);
        sdfq_reply_free(&reply);
        if (rc || end)
            return rc;
        sleep_ms(100);
    }
}

int sdfq_cmd_bake(const sdfq_server *srv, const sdfq_args *a)
{
    if (a->npos != 1) {
        fprintf(stderr, "sdfq bake: needs one mesh name (see sdfq bake --help)\n");
        return SDFQ_USAGE;
    }
    char *body = bake_body(a);
    if (!body)
        return SDFQ_USAGE;
    char *name = sdfq_escape(a->pos[0]);
    char path[800];
    snprintf(path, sizeof path, "/v1/meshes/%s/bake", name ? name : "");
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
        fprintf(stderr, "sdfq: the bake's answer has no job id\n");
        rc = SDFQ_CONNECT;
    } else if (sdfq_opt_value(a, "wait")) {
        rc = wait_job(srv, id, vol ? vol : a->pos[0]);
    } else {
        printf("%s\n", id);
    }
    cJSON_Delete(job);
    sdfq_reply_free(&reply);
    return rc;
}
