/* transport.h - libsdfclient's byte stream (internal): one non-blocking TCP connection to
 * sdfd's binary port, plain or inside TLS 1.2+ (GnuTLS), behind one interface, so that
 * pipeline.c frames, sends and receives without knowing which. Nothing here is exported
 * from the shared library (hidden visibility, besides the version script). */
#ifndef SDFC_TRANSPORT_H
#define SDFC_TRANSPORT_H

#include <stddef.h>
#include <sys/types.h>
#include <sys/uio.h>

#define SDFC__HIDDEN __attribute__((visibility("hidden")))

/* The TLS settings of a handle: the CA certificates the server's is verified against, kept
 * for every connection the handle opens. */
typedef struct sdfc__tls sdfc__tls;

/* Load `ca_file` (PEM; NULL: the system's CAs). 0, SDFC_EINVAL (a file that does not load
 * or holds no certificate) or SDFC_ENOMEM. */
SDFC__HIDDEN int sdfc__tls_new(const char *ca_file, sdfc__tls **out);
SDFC__HIDDEN void sdfc__tls_free(sdfc__tls *tls);

typedef struct sdfc__conn {
    int fd;        /* -1 when closed */
    void *session; /* gnutls_session_t, NULL for a plain connection */
    int gone;      /* TLS: the socket met its end or a reset, whatever GnuTLS makes of it */
} sdfc__conn;

/* Connect to host:port and, with `tls`, do the handshake, verifying the server's certificate
 * and that it names `host` (a DNS name or an IP address), all within timeout_ms (< 0: no
 * limit). 0, or SDFC_ECONNECT (errno says why), SDFC_ETIMEDOUT, SDFC_ETLS, SDFC_ECERT,
 * SDFC_ENOMEM; *conn is then closed, its `gone` set when the server closed or reset it
 * during the TLS handshake. A connection reset right after the server accepted it opens
 * (0): the first send or receive on it meets the reset. */
SDFC__HIDDEN int sdfc__conn_open(sdfc__conn *conn, const char *host, int port,
                                 const sdfc__tls *tls, int timeout_ms);

/* Close (a TLS connection says close_notify first if the socket takes it at once). */
SDFC__HIDDEN void sdfc__conn_close(sdfc__conn *conn);

/* Without blocking. recv: > 0 bytes, 0 at the end of the stream, -1 with errno EAGAIN,
 * EINTR, ECONNRESET (the peer went away, with TLS also without close_notify), EPROTO (a TLS
 * failure) or a socket error. send: bytes taken from the front of iov, or -1 with errno as
 * recv's (EPIPE too). A TLS send that returned EAGAIN must be repeated with the same iov. */
SDFC__HIDDEN ssize_t sdfc__conn_recv(sdfc__conn *conn, void *buf, size_t len);
SDFC__HIDDEN ssize_t sdfc__conn_send(sdfc__conn *conn, const struct iovec *iov, int iovcnt);

/* Wait up to timeout_ms (< 0: forever) until the connection can make progress on `events`
 * (POLLIN, POLLOUT): 1, 0 timed out, -1 error. With TLS, records already decrypted count as
 * readable, and a direction TLS itself waits for (a record it must finish writing) is added. */
SDFC__HIDDEN int sdfc__conn_wait(sdfc__conn *conn, short events, int timeout_ms);

#endif
