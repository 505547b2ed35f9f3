/* http.h - sdfq's HTTP requests (libcurl): one request, its answer in memory or streamed to
 * a file, the bearer token when one is set, and the server's JSON errors turned into one
 * line on stderr and an exit code. */
#ifndef SDFQ_HTTP_H
#define SDFQ_HTTP_H

#include <stdio.h>

#include "sdfq.h"

typedef struct sdfq_request {
    const char *method;       /* "GET", "PUT", "POST", "DELETE" */
    const char *path;         /* from the server's root, names already escaped */
    const void *body;         /* a body in memory, or NULL */
    size_t body_len;
    FILE *upload;             /* or a body read from a file of upload_size bytes */
    long long upload_size;
    const char *content_type; /* with a body */
    const char *save_to;      /* a 2xx answer's body goes to this file ("-": stdout) */
} sdfq_request;

typedef struct sdfq_reply {
    long status;
    char *body;               /* NUL-terminated; NULL when saved to a file */
    size_t len;
} sdfq_reply;

/* 0 when the server answered 2xx (the reply is the caller's: sdfq_reply_free); otherwise
 * SDFQ_REFUSED (the server's status, code and message printed), SDFQ_CONNECT (libcurl's
 * reason printed) or SDFQ_OUTPUT (save_to could not be written), and no reply to free. */
int sdfq_http(const sdfq_server *srv, const sdfq_request *req, sdfq_reply *reply);
void sdfq_reply_free(sdfq_reply *reply);

/* `name` escaped for a URL path segment, into a malloc'ed string (NULL: out of memory). */
char *sdfq_escape(const char *name);

/* Print the server's refusal from an error body: "sdfq: server: 404 ENOTFOUND: ...". */
void sdfq_print_refusal(long status, const char *body, size_t len);

#endif
