/* binconn.c - what the binary front end's connections share across threads (binconn.h):
 * queueing a reply frame, from any thread, and waking the poll loop to send it; counting and
 * logging a request; and a request's end. */
#include "binconn.h"

#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "errors.h"
#include "log.h"

void sdfd_bin_wake(sdfd_binary *b)
{
    uint64_t one = 1;
    ssize_t unused = write(b->wake_fd, &one, sizeof one);
    (void)unused;
}

void sdfd_bin_enqueue(connection *c, char *data, size_t len)
{
    out_frame *f = malloc(sizeof *f);
    if (!f) {
        free(data);
        return;
    }
    *f = (out_frame){NULL, data, len, 0};
    pthread_mutex_lock(&c->lock);
    if (c->out_tail)
        c->out_tail->next = f;
    else
        c->out_head = f;
    c->out_tail = f;
    c->out_bytes += len;
    pthread_mutex_unlock(&c->lock);
}

void sdfd_bin_send_error(connection *c, uint32_t id, int err, const char *message)
{
    char *frame = malloc(512);
    if (!frame)
        return;
    size_t n = sdf_proto_encode_error(frame, 512, id, (uint16_t)sdfd_http_status(err),
                                      sdfd_errname(err), message);
    sdfd_bin_enqueue(c, frame, n);
}

void sdfd_bin_account(sdfd_binary *b, sdfd_route route, const char *what, int status,
                      size_t points, double start, size_t bytes_in, size_t bytes_out)
{
    double seconds = sdfd_now() - start;
    sdfd_metrics_request(b->srv->metrics, route, status, seconds);
    sdfd_log_request("binary", what,
                     route == SDFD_ROUTE_BIN_QUERY          ? "query"
                     : route == SDFD_ROUTE_BIN_VOLUME_QUERY ? "volume_query"
                                                            : "other",
                     status, points, seconds * 1e6, bytes_in, bytes_out);
}

void sdfd_bin_request_finished(sdfd_binary *b, connection *c)
{
    pthread_mutex_lock(&c->lock);
    c->in_flight--;
    pthread_mutex_unlock(&c->lock);
    atomic_fetch_sub(&b->srv->in_flight, 1);
}

void sdfd_bin_frame_kind(uint8_t type, sdfd_route *route, const char **what)
{
    *route = type == SDF_PROTO_QUERY          ? SDFD_ROUTE_BIN_QUERY
             : type == SDF_PROTO_VOLUME_QUERY ? SDFD_ROUTE_BIN_VOLUME_QUERY
                                              : SDFD_ROUTE_BIN_OTHER;
    *what = type == SDF_PROTO_QUERY          ? "QUERY"
            : type == SDF_PROTO_VOLUME_QUERY ? "VOLUME_QUERY"
            : type == SDF_PROTO_HELLO        ? "HELLO"
            : type == SDF_PROTO_LIST_MESHES  ? "LIST_MESHES"
            : type == SDF_PROTO_AUTH         ? "AUTH"
                                             : "UNKNOWN";
}
