/* tls.h - sdfd's TLS certificate and key (--tls-cert, --tls-key): read and checked at start,
 * reloaded on SIGHUP, and handed to both front ends (tls.c). */
#ifndef SDFD_TLS_H
#define SDFD_TLS_H

#include <stddef.h>

#include <gnutls/abstract.h>
#include <gnutls/gnutls.h>

/* TLS 1.2 and 1.3 only: SSL 3.0, TLS 1.0 and 1.1 are refused in the handshake. */
#define SDFD_TLS_PRIORITIES "NORMAL:-VERS-ALL:+VERS-TLS1.3:+VERS-TLS1.2"

typedef struct sdfd_tls sdfd_tls;
/* One reading of the two files: what a session is handshaken with. */
typedef struct sdfd_tls_cert sdfd_tls_cert;

/* Read and check both files (PEM; the key must be the certificate's). 0, or -1 with the
 * reason in err. Only one sdfd_tls may exist at a time: GnuTLS's certificate callback,
 * which MHD calls, has no argument to carry it (sdfd_tls_retrieve). */
int sdfd_tls_open(const char *cert_path, const char *key_path, sdfd_tls **out, char *err,
                  size_t err_cap);
/* Read both files again: 0 and new handshakes use them; -1 (err says why) and the
 * certificate in use stays. Sessions already open keep the certificate they began with. */
int sdfd_tls_reload(sdfd_tls *tls, char *err, size_t err_cap);
/* After every session has ended. NULL is a no-op. */
void sdfd_tls_destroy(sdfd_tls *tls);

/* The binary front end: a non-blocking server session on fd with the current certificate,
 * which it holds until sdfd_tls_session_end. 0 or -1. */
int sdfd_tls_session_begin(sdfd_tls *tls, int fd, gnutls_session_t *session,
                           sdfd_tls_cert **cert);
void sdfd_tls_session_end(sdfd_tls *tls, gnutls_session_t session, sdfd_tls_cert *cert);

/* The HTTP front end (MHD owns its sessions): the certificate callback
 * (MHD_OPTION_HTTPS_CERT_CALLBACK), and a connection's start and end, which keep a
 * replaced certificate alive while a connection that may have been handshaken with it is
 * open. sdfd_tls_connection_opened returns a token for sdfd_tls_connection_closed. */
gnutls_certificate_retrieve_function2 sdfd_tls_retrieve;
void *sdfd_tls_connection_opened(sdfd_tls *tls);
void sdfd_tls_connection_closed(sdfd_tls *tls, void *token);

#endif
