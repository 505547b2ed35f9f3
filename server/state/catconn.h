/* catconn.h - connections to the catalog's PostgreSQL (libpq): opening one, a small pool of
 * them for calls from any thread, running a statement and sorting its failure.
 *
 * A connection string is a libpq URI or key=value string, taken as the user wrote it (TLS
 * through `sslmode`, `sslrootcert`...); sdfd's defaults for what it leaves out are a 10 s
 * limit on connecting (or its connect_timeout), TCP keepalives (so a peer that vanished
 * without closing is noticed within about a minute) and application_name=sdfd. Connecting is asynchronous and watches an
 * optional file descriptor, so a thread told to stop is not held by a connect attempt.
 *
 * Failures come back as the server's codes: SDFD_EUNAVAILABLE when PostgreSQL cannot be
 * reached or is going away (a lost connection, SQLSTATE classes 08, 53, 57P), with libpq's
 * message; SDFD_CATCONN_RETRY (positive) for a deadlock or serialization failure, which the
 * caller retries as a whole; SDFD_CATCONN_CONFLICT (positive) for an integrity constraint's
 * refusal (SQLSTATE class 23), which only a caller expecting one may see as anything but a
 * bug; SDF_EIO for any other statement error (a bug or a schema someone changed), with the
 * SQLSTATE and message. The positive codes never leave the catalog's modules. A connection
 * whose call failed is not reused: sdfd_catconn_put closes it unless it is idle and healthy,
 * and the next call reconnects. */
#ifndef SDFD_CATCONN_H
#define SDFD_CATCONN_H

#include <libpq-fe.h>
#include <stddef.h>

#include "state/catmetrics.h"

#define SDFD_CATCONN_RETRY 1         /* run the transaction again */
#define SDFD_CATCONN_CONFLICT 2      /* a constraint refused the statement */
#define SDFD_CATCONN_TIMEOUT_SECONDS 10 /* connecting, when the string names no connect_timeout */

typedef struct sdfd_catconn_pool sdfd_catconn_pool;

/* Check a connection string (PQconninfoParse): 0, or SDF_EINVAL with err set. */
int sdfd_catconn_check(const char *conninfo, char *err, size_t cap);

/* Open one connection. wake_fd >= 0: give up (SDF_ECANCELED) as soon as it turns readable.
 * 0 with *out set (PQfinish it), SDFD_EUNAVAILABLE or SDF_ENOMEM with err set. Counts
 * connects and failures in m (which may be NULL). Thread-safe. */
int sdfd_catconn_open(const char *conninfo, int wake_fd, sdfd_catalog_metrics *m, PGconn **out,
                      char *err, size_t cap);

/* A pool of at most max_conns connections (0: 4), opened when first needed. conninfo is
 * copied and must pass sdfd_catconn_check. NULL on out of memory. */
sdfd_catconn_pool *sdfd_catconn_pool_create(const char *conninfo, size_t max_conns,
                                            sdfd_catalog_metrics *m);
void sdfd_catconn_pool_destroy(sdfd_catconn_pool *p); /* NULL is a no-op; no call may run */

/* Take a connection: an idle one that still looks alive (*reused = 1), or a new one when
 * fewer than max_conns exist (*reused = 0); waits while all are in use. 0, or
 * SDFD_EUNAVAILABLE with err set. Give it back with sdfd_catconn_put. */
int sdfd_catconn_get(sdfd_catconn_pool *p, PGconn **out, int *reused, char *err, size_t cap);
/* Give back: kept if healthy and outside a transaction, otherwise closed. */
void sdfd_catconn_put(sdfd_catconn_pool *p, PGconn *conn);

/* Run one statement with n parameters (text, or binary where formats[i] is 1; lengths
 * matter for binary ones only) and wait for its result, text or binary (`binary`). 0 with
 * *res set when res is non-NULL (PQclear it), or an error code as above with err set. One
 * round trip, timed into m. */
int sdfd_catconn_exec(sdfd_catalog_metrics *m, PGconn *conn, const char *sql, int n,
                      const char *const *values, const int *lengths, const int *formats,
                      int binary, PGresult **res, char *err, size_t cap);

/* Like sdfd_catconn_exec, but the rows come one at a time (libpq's single-row mode), each
 * handed to row(arg, result) on the calling thread, so a large answer is never held whole;
 * row returns 0 or an error code (err set), which ends the call once the rest is drained. */
typedef int (*sdfd_catconn_row_fn)(void *arg, const PGresult *row, char *err, size_t cap);
int sdfd_catconn_stream(sdfd_catalog_metrics *m, PGconn *conn, const char *sql, int n,
                        const char *const *values, const int *lengths, const int *formats,
                        int binary, sdfd_catconn_row_fn row, void *arg, char *err, size_t cap);

/* "what: msg" into err, libpq's lines joined into one and its trailing newline dropped. */
void sdfd_catconn_message(char *err, size_t cap, const char *what, const char *msg);

/* Sort a failed statement's result (res may be NULL) into the codes above; err gets "what:
 * message". Counts SDFD_EUNAVAILABLE in m. */
int sdfd_catconn_error(sdfd_catalog_metrics *m, PGconn *conn, const PGresult *res,
                       const char *what, char *err, size_t cap);

#endif
