/* http.h - the HTTP front end (libmicrohttpd). See http.c and docs/api.md. */
#ifndef SDFD_HTTP_H
#define SDFD_HTTP_H

#include "state/server.h"

typedef struct sdfd_http sdfd_http;

/* Listen on cfg.http_addr and serve. Returns 0 or -1 (logged). */
int sdfd_http_start(sdfd_server *srv, sdfd_http **out);
/* Stop accepting connections (graceful shutdown, step 1). */
void sdfd_http_quiesce(sdfd_http *http);
/* Close everything (after in-flight requests are answered). NULL is a no-op. */
void sdfd_http_stop(sdfd_http *http);

#endif
