/* catfixture.h - what the catalog's C tests share: the PostgreSQL that run_catalog.py
 * started for them (its address from the environment), SQL run beside the catalog to look
 * at its tables, the pipe on which the test asks run_catalog.py to stop, start or kill that
 * server, and bytes, clocks and timings.
 *
 * Environment: SDFD_TEST_PG_BASE ("postgresql://postgres@127.0.0.1:PORT", no database),
 * SDFD_TEST_PG_PORT, SDFD_TEST_PGCTL ("W,R": descriptors to write a command line to and read
 * the answer line from). */
#ifndef SDFD_TESTS_CATFIXTURE_H
#define SDFD_TESTS_CATFIXTURE_H

#include <stddef.h>
#include <stdint.h>

#include "state/catalog.h"

/* The URI of database `db` (static buffer, one per thread is not needed: call, copy). */
const char *pg_uri(const char *db);
const char *pg_port(void);

/* Run sql in database db on a connection of its own; the first value of the first row,
 * malloc'd (free it), "" when there is none, NULL on failure (printed). */
char *pg_value(const char *db, const char *sql);
/* pg_value's first value as a number, or -1 on failure. */
long long pg_number(const char *db, const char *sql);
/* Create database db (dropping one of that name). 0 on success. */
int pg_create_db(const char *db);

/* Ask run_catalog.py to "stop", "start" or "kill" the server: 0 once it has. */
int pg_control(const char *command);

void fill_bytes(void *buf, size_t n, uint64_t seed);
double now_seconds(void);
/* The p-th percentile (0..100) of n values (sorted in place). */
double percentile(double *v, size_t n, double p);
/* A hash as hex for SQL: "\\x...". */
void hash_literal(const unsigned char hash[SDFD_CATALOG_HASH_BYTES], char out[70]);

/* The sections of the test (test_catalog.c, test_catalog_blobs.c, test_catalog_listen.c). */
void test_blobs(sdfd_catalog *c, const char *db);
void test_sweeper(sdfd_catalog *c, const char *db);
void test_put_delete_sweep_race(sdfd_catalog *c);
void test_listener(sdfd_catalog *c);
void test_outage(sdfd_catalog *c, const char *db);

#endif
