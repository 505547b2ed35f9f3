/* http.c - the HTTP transport on libmicrohttpd (routes in docs/api.md): a request becomes
 * an operation of the table (ops/optable.h) admitted once (ops/admission.h), and then a call
 * of its handler (ops/dispatch.h) or one of the two queries (httpquery.c); how a result is
 * answered is httpreq.c's. This file calls them, and none of them calls back.
 *
 * MHD's threads only do I/O: they receive bodies, parse them, format replies. Geometry runs
 * elsewhere: a query becomes a batcher job and an upload or a slice a worker thread's task,
 * and the connection is suspended (sdfd_http_wait) until that work resumes it.
 *
 * Each request walks the same steps: `admit` (operation, method, auth, URL arguments,
 * Content-Length, all checked from the headers before any body byte is read), `receive`
 * (append the body, never past its declared length), `dispatch` (start the work, or answer
 * at once), and after a resume, its `respond`. The completion callback counts, logs and
 * frees. */
#include "transport/http.h"

#include <cjson/cJSON.h>
#include <microhttpd.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "core/errors.h"
#include "core/log.h"
#include "ops/admission.h"
#include "ops/dispatch.h"
#include "ops/urlargs.h"
#include "transport/body.h"
#include "transport/httpframing.h"
#include "transport/httpquery.h"
#include "transport/httpreq.h"
#include "transport/httpwatch.h"
#include "transport/tls.h"
#include "transport/net.h"
#include "transport/page.h"

struct sdfd_http {
    sdfd_server *srv;
    struct MHD_Daemon *daemon;
    sdfd_httpwatch *watch; /* cuts off requests that arrive too slowly */
    int listen_fd;
    int quiesced; /* listen_fd handed back by MHD_quiesce_daemon: ours to close */
};

typedef sdfd_http_request request;

/* ---- admission: everything decided from the request line and headers ------------------- */

/* The bearer token, when the request presents the right one. */
static int token_ok(const request *req)
{
    const sdfd_config *cfg = &req->srv->cfg;
    const char *h = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                MHD_HTTP_HEADER_AUTHORIZATION);
    return h && !strncmp(h, "Bearer ", 7) && sdfd_token_matches(cfg, h + 7, strlen(h + 7));
}

/* The operation (optable.h) and the checks every operation passes (admission.h). */
static enum MHD_Result admit_operation(request *req, const char *url)
{
    char msg[300];
    int rc = sdfd_op_match(req->method, url, &req->op, req->name, sizeof req->name);
    if (rc == SDF_ENOTFOUND)
        return sdfd_http_error(req, rc, "no route %s", url);
    if (rc == SDF_EINVAL)
        return sdfd_http_error(req, rc, "names are 1-255 characters of A-Z a-z 0-9 . _ - "
                                        "and do not start with '.'");
    if (rc == SDFD_EMETHOD)
        return sdfd_http_error(req, rc, "%s is not allowed on %s", req->method, req->op->path);
    rc = sdfd_admit(req->srv, req->op, token_ok(req), msg, sizeof msg);
    if (rc == SDFD_EUNAUTHORIZED)
        return sdfd_http_error(req, rc, "this request needs 'Authorization: Bearer <token>'");
    enum MHD_Result refused;
    if (sdfd_http_check_args(req, &refused))
        return refused;
    if (rc)
        return sdfd_http_error(req, rc, "%s", msg);
    return MHD_YES;
}

/* Decide from the headers alone; returns MHD_YES with a response queued if refused. */
static enum MHD_Result admit(request *req, const char *url)
{
    sdfd_server *srv = req->srv;
    char framing[256];
    if (sdfd_http_framing_check(req->conn, framing, sizeof framing))
        return sdfd_http_error(req, SDFD_ESYNTAX, "%s", framing);
    enum MHD_Result r = admit_operation(req, url);
    if (r != MHD_YES || req->answered || !(req->op->flags & SDFD_OP_BODY))
        return r;
    const char *cl = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                 MHD_HTTP_HEADER_CONTENT_LENGTH);
    char *end;
    unsigned long long declared = cl ? strtoull(cl, &end, 10) : 0;
    if (!cl || !*cl || *end)
        return sdfd_http_error(req, SDFD_ELENGTH, "send the body with a Content-Length header");
    if (declared > srv->cfg.max_body_bytes)
        return sdfd_http_error(req, SDF_ELIMIT, "the body is %llu bytes, over the limit of %zu",
                               declared, srv->cfg.max_body_bytes);
    /* The whole body in one allocation, sized by a checked length, NUL-terminated, and
     * counted against the budget of all connections until the request completes. */
    req->declared = (size_t)declared;
    if (sdfd_buffer_reserve(srv, req->declared + 1))
        return sdfd_http_error(req, SDFD_EBUSY, SDFD_BUFFER_BUSY_FMT, srv->cfg.max_buffered_bytes);
    req->reserved = req->declared + 1;
    req->body = malloc(req->declared + 1);
    if (!req->body)
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory for a %zu-byte body", req->declared);
    req->body[0] = '\0';
    return MHD_YES;
}

/* ---- work -------------------------------------------------------------------------------- */

static enum MHD_Result reply_call(request *req)
{
    req->points = req->call.points;
    return sdfd_http_result(req, &req->call.result);
}

static void call_done(sdfd_call *call)
{
    sdfd_http_resume(call->user);
}

/* An operation of call.h: the request as a call, run; an asynchronous one with the
 * connection suspended first, so the worker's resume cannot come before it. */
static enum MHD_Result run_call(request *req)
{
    req->call = (sdfd_call){.srv = req->srv, .op = req->op, .name = req->name,
                            .args = &req->args, .body = req->body, .len = req->len,
                            .done = call_done, .user = req};
    int async = req->op->flags & SDFD_OP_ASYNC;
    if (async)
        sdfd_http_wait(req, reply_call);
    if (sdfd_dispatch(&req->call) == SDFD_CALL_PENDING)
        return MHD_YES;
    if (async)
        sdfd_http_unwait(req);
    return reply_call(req);
}

static enum MHD_Result dispatch(request *req)
{
    switch (req->op->id) {
    case SDFD_OP_QUERY:
        return sdfd_http_query(req);
    case SDFD_OP_VOLUME_QUERY:
        return sdfd_http_volume_query(req);
    case SDFD_OP_PAGE:
    case SDFD_OP_STATIC:
        return sdfd_http_page(req);
    default:
        return run_call(req);
    }
}

/* ---- MHD callbacks ----------------------------------------------------------------------- */

static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url,
                                  const char *method, const char *version,
                                  const char *upload_data, size_t *upload_size, void **state)
{
    (void)version;
    sdfd_http *http = cls;
    request *req = *state;
    if (!req) { /* headers are in: admit or refuse before reading the body */
        req = calloc(1, sizeof *req);
        if (!req)
            return MHD_NO;
        req->srv = http->srv;
        req->conn = conn;
        req->method = method;
        req->start = sdfd_now();
        atomic_fetch_add(&http->srv->in_flight, 1);
        *state = req;
        return admit(req, url);
    }
    if (*upload_size)
        sdfd_httpwatch_received(http->watch, conn, *upload_size);
    else
        sdfd_httpwatch_arrived(http->watch, conn);
    if (req->answered) {
        *upload_size = 0; /* refused from the headers: MHD discards the rest */
        return MHD_YES;
    }
    if (*upload_size) { /* more body */
        size_t n = *upload_size;
        if (n > req->declared - req->len)
            n = req->declared - req->len; /* never past the declared length */
        memcpy(req->body + req->len, upload_data, n);
        req->len += n;
        req->body[req->len] = '\0';
        *upload_size = 0;
        return MHD_YES;
    }
    if (req->waiting) { /* resumed: the work is done */
        if (!atomic_load(&req->finished))
            return MHD_YES;
        return req->respond(req);
    }
    return dispatch(req);
}

static void on_completed(void *cls, struct MHD_Connection *conn, void **state,
                         enum MHD_RequestTerminationCode code)
{
    (void)code;
    sdfd_http *http = cls;
    sdfd_httpwatch_next(http->watch, conn);
    request *req = *state;
    if (!req)
        return;
    sdfd_server *srv = req->srv;
    int status = req->answered ? req->status : 499; /* client went away */
    sdfd_account(srv, &(sdfd_answered){.op = req->op, .what = req->method, .status = status,
                                       .points = req->points, .start = req->start,
                                       .bytes_in = req->len, .bytes_out = req->bytes_out});
    sdfd_query_release(&req->query);
    sdfd_volume_query_release(&req->volume_query);
    if (req->call.srv)
        sdfd_call_release(&req->call);
    if (req->points_owned)
        free(req->points_buf);
    free(req->reply.buffer);
    free(req->body);
    sdfd_buffer_release(srv, req->reserved);
    atomic_fetch_sub(&srv->in_flight, 1);
    free(req);
    *state = NULL;
}

static void on_mhd_log(void *cls, const char *fmt, va_list ap)
{
    (void)cls;
    char message[512];
    vsnprintf(message, sizeof message, fmt, ap);
    message[strcspn(message, "\n")] = '\0';
    sdfd_log("warn", "http", "%s", message);
}

static int hex_digit(char c)
{
    return c >= '0' && c <= '9' ? c - '0'
           : c >= 'a' && c <= 'f' ? c - 'a' + 10
           : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                  : -1;
}

/* URL paths and arguments decoded as MHD's default does (%HH), except that %00 stays as it
 * is: every route reads the decoded text as a C string, so a decoded NUL would cut
 * "/v1/meshes/a%00b" to the mesh "a"; kept literal, the name is refused for its '%'. */
static size_t unescape_url(void *cls, struct MHD_Connection *connection, char *s)
{
    (void)cls, (void)connection;
    char *out = s;
    for (const char *in = s; *in;) {
        int hi = in[0] == '%' ? hex_digit(in[1]) : -1, lo = hi >= 0 ? hex_digit(in[2]) : -1;
        if (lo >= 0 && (hi || lo)) {
            *out++ = (char)(hi * 16 + lo);
            in += 3;
        } else {
            *out++ = *in++;
        }
    }
    *out = '\0';
    return (size_t)(out - s);
}

/* What sdfd keeps per connection: its entry in the slow-request watch (httpwatch.c) and,
 * with TLS, its hold on the certificate it may have been handshaken with (tls.c). */
typedef struct connection_context {
    void *watch; /* first: httpwatch.c reads it through the socket context */
    void *tls;
} connection_context;

/* A connection opens or closes: it is watched for requests that arrive too slowly, and with
 * TLS a certificate replaced by a reload is freed only once no connection that may have been
 * handshaken with it is open. */
static void on_connection(void *cls, struct MHD_Connection *connection, void **socket_context,
                          enum MHD_ConnectionNotificationCode code)
{
    sdfd_http *http = cls;
    connection_context *ctx = *socket_context;
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        ctx = calloc(1, sizeof *ctx);
        *socket_context = ctx;
        if (!ctx)
            return; /* unwatched, and no certificate is held: MHD's idle timeout applies */
        sdfd_httpwatch_notify(http->watch, connection, &ctx->watch, code);
        if (http->srv->tls)
            ctx->tls = sdfd_tls_connection_opened(http->srv->tls);
        return;
    }
    if (!ctx)
        return;
    sdfd_httpwatch_notify(http->watch, connection, &ctx->watch, code);
    if (ctx->tls)
        sdfd_tls_connection_closed(http->srv->tls, ctx->tls);
    free(ctx);
    *socket_context = NULL;
}

int sdfd_http_start(sdfd_server *srv, sdfd_http **out)
{
    int port;
    int fd = sdfd_listen(srv->cfg.http_addr, &port);
    if (fd < 0)
        return -1;
    sdfd_http *http = calloc(1, sizeof *http);
    http->srv = srv;
    http->listen_fd = fd;
    http->watch = sdfd_httpwatch_start(srv->cfg.timeout_seconds);
    if (!http->watch) {
        close(fd);
        free(http);
        return -1;
    }
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_EPOLL | MHD_ALLOW_SUSPEND_RESUME |
                     MHD_USE_ERROR_LOG;
    /* HTTPS: MHD asks sdfd_tls_retrieve for the certificate at each handshake, so a reload
     * (SIGHUP) reaches new connections without restarting the daemon. */
    struct MHD_OptionItem tls_options[] = {
        {MHD_OPTION_HTTPS_CERT_CALLBACK, 0, (void *)sdfd_tls_retrieve},
        {MHD_OPTION_HTTPS_PRIORITIES, 0, (void *)SDFD_TLS_PRIORITIES},
        {MHD_OPTION_END, 0, NULL},
    };
    if (srv->tls)
        flags |= MHD_USE_TLS;
    else
        tls_options[0].option = MHD_OPTION_END;
    http->daemon = MHD_start_daemon(
        flags, 0, NULL, NULL, on_request, http,
        MHD_OPTION_EXTERNAL_LOGGER, on_mhd_log, http, /* first, so every message goes through it */
        MHD_OPTION_LISTEN_SOCKET, fd,
        MHD_OPTION_THREAD_POOL_SIZE, 2u,
        MHD_OPTION_CONNECTION_LIMIT, srv->cfg.max_connections,
        MHD_OPTION_PER_IP_CONNECTION_LIMIT, srv->cfg.max_per_ip,
        MHD_OPTION_CONNECTION_TIMEOUT, srv->cfg.timeout_seconds,
        MHD_OPTION_NOTIFY_COMPLETED, on_completed, http,
        MHD_OPTION_NOTIFY_CONNECTION, on_connection, http,
        MHD_OPTION_UNESCAPE_CALLBACK, unescape_url, NULL,
        MHD_OPTION_ARRAY, tls_options,
        MHD_OPTION_END);
    if (!http->daemon) {
        sdfd_log("error", "listen", "libmicrohttpd failed to start on %s%s", srv->cfg.http_addr,
                 srv->tls && MHD_is_feature_supported(MHD_FEATURE_HTTPS_CERT_CALLBACK) != MHD_YES
                     ? ": this libmicrohttpd has no HTTPS certificate callback (GnuTLS 3)"
                     : "");
        sdfd_httpwatch_stop(http->watch);
        close(fd);
        free(http);
        return -1;
    }
    sdfd_log_listening("http", srv->cfg.http_addr, port);
    *out = http;
    return 0;
}

/* MHD stops accepting and hands the listening socket back. It is shut down at once, so new
 * connections are refused while the rest drains, but closed only after MHD's threads have
 * stopped: closed here, its number could be reused while a worker still held it in its
 * epoll set (ThreadSanitizer reported the close racing a worker's epoll_ctl). */
void sdfd_http_quiesce(sdfd_http *http)
{
    int fd = MHD_quiesce_daemon(http->daemon);
    if (fd >= 0) {
        shutdown(fd, SHUT_RDWR);
        http->listen_fd = fd;
        http->quiesced = 1;
    }
}

void sdfd_http_stop(sdfd_http *http)
{
    if (!http)
        return;
    MHD_stop_daemon(http->daemon);
    sdfd_httpwatch_stop(http->watch);
    if (http->quiesced)
        close(http->listen_fd);
    free(http);
}
