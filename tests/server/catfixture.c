/* catfixture.c - the catalog tests' shared helpers (see catfixture.h). */
#include "catfixture.h"

#include <libpq-fe.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

const char *pg_uri(const char *db)
{
    static char uri[512];
    const char *base = getenv("SDFD_TEST_PG_BASE");
    snprintf(uri, sizeof uri, "%s/%s", base ? base : "postgresql://", db);
    return uri;
}

const char *pg_port(void)
{
    const char *port = getenv("SDFD_TEST_PG_PORT");
    return port ? port : "5432";
}

char *pg_value(const char *db, const char *sql)
{
    PGconn *conn = PQconnectdb(pg_uri(db));
    char *out = NULL;
    if (PQstatus(conn) != CONNECTION_OK) {
        fprintf(stderr, "pg_value: %s", PQerrorMessage(conn));
    } else {
        PGresult *r = PQexec(conn, sql);
        ExecStatusType st = PQresultStatus(r);
        if (st == PGRES_TUPLES_OK || st == PGRES_COMMAND_OK)
            out = strdup(PQntuples(r) && PQnfields(r) ? PQgetvalue(r, 0, 0) : "");
        else
            fprintf(stderr, "pg_value(%s): %s", sql, PQresultErrorMessage(r));
        PQclear(r);
    }
    PQfinish(conn);
    return out;
}

long long pg_number(const char *db, const char *sql)
{
    char *v = pg_value(db, sql);
    long long n = v && *v ? atoll(v) : -1;
    free(v);
    return n;
}

int pg_create_db(const char *db)
{
    char sql[256];
    snprintf(sql, sizeof sql, "DROP DATABASE IF EXISTS %s", db);
    char *a = pg_value("postgres", sql);
    snprintf(sql, sizeof sql, "CREATE DATABASE %s", db);
    char *b = a ? pg_value("postgres", sql) : NULL;
    int ok = a && b;
    free(a);
    free(b);
    return ok ? 0 : -1;
}

int pg_control(const char *command)
{
    int wfd = -1, rfd = -1;
    const char *fds = getenv("SDFD_TEST_PGCTL");
    if (!fds || sscanf(fds, "%d,%d", &wfd, &rfd) != 2)
        return -1;
    char line[256];
    int n = snprintf(line, sizeof line, "%s\n", command);
    if (write(wfd, line, (size_t)n) != n)
        return -1;
    size_t got = 0;
    while (got + 1 < sizeof line && read(rfd, line + got, 1) == 1 && line[got] != '\n')
        got++;
    line[got] = '\0';
    if (strcmp(line, "ok"))
        fprintf(stderr, "pg_control(%s): %s\n", command, line);
    return strcmp(line, "ok") ? -1 : 0;
}

void fill_bytes(void *buf, size_t n, uint64_t seed)
{
    unsigned char *p = buf;
    uint64_t x = seed * 0x9e3779b97f4a7c15ull + 1;
    for (size_t i = 0; i < n; i++) {
        x ^= x << 13, x ^= x >> 7, x ^= x << 17;
        p[i] = (unsigned char)(x >> 32);
    }
}

double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double percentile(double *v, size_t n, double p)
{
    if (n == 0)
        return 0;
    qsort(v, n, sizeof *v, cmp_double);
    size_t i = (size_t)(p / 100.0 * (double)(n - 1) + 0.5);
    return v[i < n ? i : n - 1];
}

void hash_literal(const unsigned char hash[SDFD_CATALOG_HASH_BYTES], char out[70])
{
    strcpy(out, "\\x");
    for (int i = 0; i < SDFD_CATALOG_HASH_BYTES; i++)
        snprintf(out + 2 + 2 * i, 3, "%02x", hash[i]);
}
