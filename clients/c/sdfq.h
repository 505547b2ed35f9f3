/* sdfq.h - what sdfq's modules share: its exit codes (docs/sdfq.md promises them to
 * scripts) and where the server is. */
#ifndef SDFQ_H
#define SDFQ_H

enum {
    SDFQ_OK = 0,
    SDFQ_USAGE = 1,   /* bad command line */
    SDFQ_REFUSED = 2, /* the server said no; its status, code and message are on stderr */
    SDFQ_CONNECT = 3, /* cannot connect, or the connection failed, timed out or made no sense */
    SDFQ_INPUT = 4,   /* an input file is missing, unreadable or malformed */
    SDFQ_OUTPUT = 5,  /* cannot write the output */
};

typedef struct sdfq_server {
    const char *url;   /* HTTP base URL, no trailing slash needed */
    char bin_host[256];
    int bin_port;
    const char *token; /* NULL: none */
    int timeout_ms;    /* the reply timeout of either protocol */
    const char *cacert; /* the CA certificates (PEM) that https and --bin-tls verify the
                           server against; NULL: the system's */
    int bin_tls;       /* the binary port speaks TLS (sdfd --bin-tls) */
} sdfq_server;

#endif
