/* catschema.h - the catalog's tables in PostgreSQL, created and migrated at start.
 *
 * sdfd_schema holds the schema's version (one row); each later version is one more step in
 * catschema.c's list, applied in order, never edited once released. The whole migration is
 * one transaction that first takes a transaction-scoped advisory lock, so replicas starting
 * together migrate once: the others wait for the lock, then find the version current. A
 * database whose schema is newer than this sdfd knows is refused rather than written. */
#ifndef SDFD_CATSCHEMA_H
#define SDFD_CATSCHEMA_H

#include <libpq-fe.h>
#include <stddef.h>

#include "state/catmetrics.h"

#define SDFD_CATSCHEMA_VERSION 2 /* the version this sdfd writes */

/* Bring conn's database to SDFD_CATSCHEMA_VERSION. 0 with *applied = the steps this call
 * applied (0 when it was current), or an error code (catconn.h) with err set; SDF_EFORMAT
 * when the database's schema is newer. m may be NULL. */
int sdfd_catschema_migrate(sdfd_catalog_metrics *m, PGconn *conn, int *applied, char *err,
                           size_t cap);

#endif
