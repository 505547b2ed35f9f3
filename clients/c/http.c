/* http.c - sdfq's HTTP requests over libcurl (http.h). A download is written to its file
 * only once the status says it is the data and not the server's JSON error, so a refused
 * download leaves no file behind. */
#include "http.h"

#include <cJSON.h>
#include <curl/curl.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>

typedef struct sink {
    CURL *curl;
    char *buf;
    size_t len, cap;
    const char *save_to;
    FILE *file;
    int write_failed;
} sink;

static size_t on_data(char *data, size_t one, size_t n, void *user)
{
    sink *s = user;
    long status = 0;
    curl_easy_getinfo(s->curl, CURLINFO_RESPONSE_CODE, &status);
    if (s->save_to && status < 300) {
        if (!s->file)
            s->file = strcmp(s->save_to, "-") ? fopen(s->save_to, "wb") : stdout;
        if (!s->file || fwrite(data, 1, n, s->file) != n) {
            s->write_failed = errno ? errno : EIO;
            return 0;
        }
        return n * one;
    }
    if (s->len + n + 1 > s->cap) {
        size_t cap = (s->len + n + 1) * 2;
        char *grown = realloc(s->buf, cap);
        if (!grown)
            return 0;
        s->buf = grown;
        s->cap = cap;
    }
    memcpy(s->buf + s->len, data, n);
    s->len += n;
    s->buf[s->len] = 0;
    return n * one;
}

void sdfq_print_refusal(long status, const char *body, size_t len)
{
    cJSON *root = body ? cJSON_ParseWithLength(body, len) : NULL;
    cJSON *err = cJSON_GetObjectItemCaseSensitive(root, "error");
    const char *code = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(err, "code"));
    const char *message = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(err, "message"));
    if (code && message)
        fprintf(stderr, "sdfq: server: %ld %s: %s\n", status, code, message);
    else
        fprintf(stderr, "sdfq: server: HTTP %ld: %.200s\n", status, body ? body : "");
    cJSON_Delete(root);
}

static void set_body(CURL *curl, const sdfq_request *req, struct curl_slist **headers)
{
    if (req->upload) {
        curl_easy_setopt(curl, CURLOPT_UPLOAD, 1L);
        curl_easy_setopt(curl, CURLOPT_READDATA, req->upload);
        curl_easy_setopt(curl, CURLOPT_INFILESIZE_LARGE, (curl_off_t)req->upload_size);
    } else if (req->body || !strcmp(req->method, "POST")) {
        curl_easy_setopt(curl, CURLOPT_POSTFIELDS, req->body ? req->body : "");
        curl_easy_setopt(curl, CURLOPT_POSTFIELDSIZE_LARGE, (curl_off_t)req->body_len);
    }
    if (req->content_type) {
        char line[128];
        snprintf(line, sizeof line, "Content-Type: %s", req->content_type);
        *headers = curl_slist_append(*headers, line);
    }
    /* the server answers at once; curl's wait for "100 Continue" would only add a second */
    *headers = curl_slist_append(*headers, "Expect:");
    curl_easy_setopt(curl, CURLOPT_CUSTOMREQUEST, req->method);
    if (!strcmp(req->method, "GET"))
        curl_easy_setopt(curl, CURLOPT_HTTPGET, 1L);
}

static int finish(const sdfq_server *srv, CURLcode cc, sink *s, long status, sdfq_reply *reply)
{
    if (s->file && s->file != stdout && fclose(s->file) && !s->write_failed)
        s->write_failed = errno ? errno : EIO;
    if (s->write_failed) {
        fprintf(stderr, "sdfq: cannot write %s: %s\n", s->save_to, strerror(s->write_failed));
        return SDFQ_OUTPUT;
    }
    if (cc != CURLE_OK) {
        fprintf(stderr, "sdfq: cannot reach %s: %s\n", srv->url, curl_easy_strerror(cc));
        return SDFQ_CONNECT;
    }
    if (status >= 300) {
        sdfq_print_refusal(status, s->buf, s->len);
        return SDFQ_REFUSED;
    }
    if (s->save_to && !s->file && strcmp(s->save_to, "-")) { /* an empty body: still a file */
        FILE *f = fopen(s->save_to, "wb");
        if (!f || fclose(f)) {
            fprintf(stderr, "sdfq: cannot write %s: %s\n", s->save_to, strerror(errno));
            return SDFQ_OUTPUT;
        }
    }
    *reply = (sdfq_reply){.status = status, .body = s->buf, .len = s->len};
    s->buf = NULL;
    return 0;
}

int sdfq_http(const sdfq_server *srv, const sdfq_request *req, sdfq_reply *reply)
{
    CURL *curl = curl_easy_init();
    if (!curl) {
        fprintf(stderr, "sdfq: cannot start libcurl\n");
        return SDFQ_CONNECT;
    }
    size_t base = strlen(srv->url);
    while (base > 0 && srv->url[base - 1] == '/')
        base--;
    char *url = malloc(base + strlen(req->path) + 1);
    if (!url) {
        curl_easy_cleanup(curl);
        return SDFQ_CONNECT;
    }
    memcpy(url, srv->url, base);
    strcpy(url + base, req->path);
    struct curl_slist *headers = NULL;
    char auth[1100];
    if (srv->token) {
        snprintf(auth, sizeof auth, "Authorization: Bearer %s", srv->token);
        headers = curl_slist_append(headers, auth);
    }
    sink s = {.curl = curl, .save_to = req->save_to};
    curl_easy_setopt(curl, CURLOPT_URL, url);
    curl_easy_setopt(curl, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(curl, CURLOPT_CONNECTTIMEOUT_MS, 10000L);
    curl_easy_setopt(curl, CURLOPT_TIMEOUT_MS, (long)srv->timeout_ms);
    if (srv->cacert) /* https:// verifies the server against these CAs, not the system's */
        curl_easy_setopt(curl, CURLOPT_CAINFO, srv->cacert);
    curl_easy_setopt(curl, CURLOPT_WRITEFUNCTION, on_data);
    curl_easy_setopt(curl, CURLOPT_WRITEDATA, &s);
    set_body(curl, req, &headers);
    curl_easy_setopt(curl, CURLOPT_HTTPHEADER, headers);
    CURLcode cc = curl_easy_perform(curl);
    long status = 0;
    curl_easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &status);
    int rc = finish(srv, cc, &s, status, reply);
    free(s.buf);
    curl_slist_free_all(headers);
    curl_easy_cleanup(curl);
    free(url);
    return rc;
}

void sdfq_reply_free(sdfq_reply *reply)
{
    free(reply->body);
    *reply = (sdfq_reply){0};
}

char *sdfq_escape(const char *name)
{
    char *e = curl_easy_escape(NULL, name, 0);
    char *copy = e ? strdup(e) : NULL;
    curl_free(e);
    return copy;
}
