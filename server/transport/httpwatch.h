/* httpwatch.h - deadlines for HTTP requests to arrive (httpwatch.c). libmicrohttpd's
 * --timeout closes a connection that sends nothing for that long, but every byte restarts
 * it, so a client trickling a byte a second (slow-loris) would hold a connection, and with
 * enough of them every connection, for ever. Here each request must arrive whole, headers
 * and body, within --timeout of its start plus a second per SDFD_HTTP_MIN_RATE body bytes;
 * a thread cuts off the connections past it. The clock runs from the connection's start or
 * the end of its previous request until the request has arrived, and not while the request
 * is worked on or answered. */
#ifndef SDFD_HTTPWATCH_H
#define SDFD_HTTPWATCH_H

#include <microhttpd.h>
#include <stddef.h>

#define SDFD_HTTP_MIN_RATE (64.0 * 1024) /* body bytes a second, after the timeout */

typedef struct sdfd_httpwatch sdfd_httpwatch;

/* Start the watching thread (NULL when it cannot start). */
sdfd_httpwatch *sdfd_httpwatch_start(unsigned timeout_seconds);
/* Stop it; after MHD_stop_daemon, which has closed every connection. */
void sdfd_httpwatch_stop(sdfd_httpwatch *w);

/* Called from MHD_OPTION_NOTIFY_CONNECTION's callback (cls: the watch): a connection starts
 * or ends. `entry` is where the connection's entry is kept: the first member of the struct
 * the connection's socket context points to, which the functions below read. */
void sdfd_httpwatch_notify(void *cls, struct MHD_Connection *conn, void **entry,
                           enum MHD_ConnectionNotificationCode code);
/* The request on conn received `bytes` more of its body. */
void sdfd_httpwatch_received(sdfd_httpwatch *w, struct MHD_Connection *conn, size_t bytes);
/* The request on conn has arrived whole: its clock stops. */
void sdfd_httpwatch_arrived(sdfd_httpwatch *w, struct MHD_Connection *conn);
/* The request on conn ended: the connection's next request starts its clock. */
void sdfd_httpwatch_next(sdfd_httpwatch *w, struct MHD_Connection *conn);

#endif
