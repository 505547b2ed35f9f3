/* transport.c - libsdfclient's byte stream (transport.h): a non-blocking TCP connection,
 * optionally inside TLS through GnuTLS. GnuTLS reads and writes the socket through our own
 * push and pull functions, so that a write never raises SIGPIPE (MSG_NOSIGNAL) and the
 * socket's errno survives GnuTLS's return codes, which pipeline.c needs to tell a peer that
 * went away (a connection it may replace) from other failures. */
#include "transport.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <gnutls/gnutls.h>

#include "sdfclient.h"

/* TLS 1.2 and 1.3 only, as sdfd itself accepts (docs/api.md, "TLS"). */
#define TLS_PRIORITIES "NORMAL:-VERS-ALL:+VERS-TLS1.3:+VERS-TLS1.2"

struct sdfc__tls {
    gnutls_certificate_credentials_t cred;
};

int sdfc__tls_new(const char *ca_file, sdfc__tls **out)
{
    *out = NULL;
    sdfc__tls *t = calloc(1, sizeof *t);
    if (!t || gnutls_certificate_allocate_credentials(&t->cred) < 0) {
        free(t);
        return SDFC_ENOMEM;
    }
    int n = ca_file ? gnutls_certificate_set_x509_trust_file(t->cred, ca_file, GNUTLS_X509_FMT_PEM)
                    : gnutls_certificate_set_x509_system_trust(t->cred);
    if (ca_file && n <= 0) { /* unreadable, or no PEM certificate in it */
        sdfc__tls_free(t);
        return SDFC_EINVAL;
    }
    *out = t;
    return 0;
}

void sdfc__tls_free(sdfc__tls *tls)
{
    if (!tls)
        return;
    gnutls_certificate_free_credentials(tls->cred);
    free(tls);
}

/* ---- the socket -------------------------------------------------------------------------- */

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

/* Milliseconds left until `deadline` for poll (-1: none), 0 once it has passed. */
static int left_ms(double deadline)
{
    if (deadline < 0)
        return -1;
    double l = deadline - now_ms();
    return l <= 0 ? 0 : l > 1e9 ? 1000000000 : (int)l + 1;
}

static int poll_fd(int fd, short events, int timeout_ms)
{
    struct pollfd p = {.fd = fd, .events = events};
    for (;;) {
        int r = poll(&p, 1, timeout_ms);
        if (r >= 0)
            return r;
        if (errno != EINTR)
            return -1;
    }
}

static int connect_one(const struct addrinfo *ai, double deadline, int *fd_out)
{
    int fd = socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC, ai->ai_protocol);
    if (fd < 0)
        return SDFC_ECONNECT;
    fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
    int rc = SDFC_ECONNECT;
    if (connect(fd, ai->ai_addr, ai->ai_addrlen) == 0) {
        rc = 0;
    } else if (errno == EINPROGRESS) {
        int r = poll_fd(fd, POLLOUT, left_ms(deadline));
        int soerr = 0;
        socklen_t len = sizeof soerr;
        if (r == 0)
            rc = SDFC_ETIMEDOUT;
        else if (r > 0 && !getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &len) &&
                 (!soerr || soerr == ECONNRESET))
            rc = 0; /* reset once accepted: the first send or receive says so, as for a
                       reset a moment later, and the connection may be replaced */
        else if (soerr)
            errno = soerr;
    }
    if (rc) {
        int saved = errno;
        close(fd);
        errno = saved;
        return rc;
    }
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    *fd_out = fd;
    return 0;
}

static int tcp_connect(const char *host, int port, double deadline, int *fd)
{
    char service[16];
    snprintf(service, sizeof service, "%d", port);
    struct addrinfo hints = {.ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM,
                             .ai_flags = AI_NUMERICSERV}, *list;
    if (getaddrinfo(host, service, &hints, &list))
        return SDFC_ECONNECT;
    int rc = SDFC_ECONNECT;
    *fd = -1;
    for (struct addrinfo *ai = list; ai && *fd < 0; ai = ai->ai_next)
        rc = connect_one(ai, deadline, fd);
    freeaddrinfo(list);
    return *fd < 0 ? rc : 0;
}

/* ---- TLS --------------------------------------------------------------------------------- */

static ssize_t tls_push(gnutls_transport_ptr_t ptr, const giovec_t *iov, int iovcnt)
{
    sdfc__conn *conn = ptr;
    struct msghdr m = {.msg_iov = (struct iovec *)iov, .msg_iovlen = (size_t)iovcnt};
    ssize_t n = sendmsg(conn->fd, &m, MSG_NOSIGNAL | MSG_DONTWAIT);
    conn->gone |= n < 0 && (errno == EPIPE || errno == ECONNRESET);
    return n;
}

/* A stream that ends inside a record is GnuTLS's E_PREMATURE_TERMINATION or
 * E_UNEXPECTED_PACKET_LENGTH, depending on where; `gone` says what happened plainly. */
static ssize_t tls_pull(gnutls_transport_ptr_t ptr, void *buf, size_t len)
{
    sdfc__conn *conn = ptr;
    ssize_t n = recv(conn->fd, buf, len, MSG_DONTWAIT);
    conn->gone |= n == 0 || (n < 0 && errno == ECONNRESET);
    return n;
}

static int tls_pull_timeout(gnutls_transport_ptr_t ptr, unsigned ms)
{
    sdfc__conn *conn = ptr;
    return poll_fd(conn->fd, POLLIN, ms == GNUTLS_INDEFINITE_TIMEOUT ? -1 : (int)ms);
}

static int is_address(const char *host)
{
    unsigned char buf[sizeof(struct in6_addr)];
    return inet_pton(AF_INET, host, buf) == 1 || inet_pton(AF_INET6, host, buf) == 1;
}

static int tls_session(sdfc__conn *conn, const char *host, const sdfc__tls *tls)
{
    gnutls_session_t s;
    if (gnutls_init(&s, GNUTLS_CLIENT | GNUTLS_NONBLOCK) < 0)
        return SDFC_ENOMEM;
    conn->session = s;
    /* SNI carries names only; an address is checked against the certificate's IP SANs */
    if (gnutls_priority_set_direct(s, TLS_PRIORITIES, NULL) < 0 ||
        gnutls_credentials_set(s, GNUTLS_CRD_CERTIFICATE, tls->cred) < 0 ||
        (!is_address(host) && gnutls_server_name_set(s, GNUTLS_NAME_DNS, host, strlen(host)) < 0))
        return SDFC_ENOMEM;
    gnutls_session_set_verify_cert(s, host, 0);
    gnutls_transport_set_ptr(s, conn);
    gnutls_transport_set_vec_push_function(s, tls_push);
    gnutls_transport_set_pull_function(s, tls_pull);
    gnutls_transport_set_pull_timeout_function(s, tls_pull_timeout);
    gnutls_handshake_set_timeout(s, GNUTLS_INDEFINITE_TIMEOUT); /* ours is `deadline` */
    return 0;
}

static int tls_handshake(sdfc__conn *conn, double deadline)
{
    for (;;) {
        int rc = gnutls_handshake(conn->session);
        if (rc == GNUTLS_E_SUCCESS)
            return 0;
        if (rc == GNUTLS_E_CERTIFICATE_VERIFICATION_ERROR)
            return SDFC_ECERT;
        if (rc != GNUTLS_E_AGAIN && gnutls_error_is_fatal(rc))
            return SDFC_ETLS;
        if (rc == GNUTLS_E_AGAIN) {
            short ev = gnutls_record_get_direction(conn->session) ? POLLOUT : POLLIN;
            int r = poll_fd(conn->fd, ev, left_ms(deadline));
            if (r == 0)
                return SDFC_ETIMEDOUT;
            if (r < 0)
                return SDFC_ETLS;
        }
    }
}

/* ---- the interface ----------------------------------------------------------------------- */

int sdfc__conn_open(sdfc__conn *conn, const char *host, int port, const sdfc__tls *tls,
                    int timeout_ms)
{
    *conn = (sdfc__conn){.fd = -1};
    double deadline = timeout_ms < 0 ? -1 : now_ms() + timeout_ms;
    int rc = tcp_connect(host, port, deadline, &conn->fd);
    if (!rc && tls && !(rc = tls_session(conn, host, tls)))
        rc = tls_handshake(conn, deadline);
    if (rc) {
        int saved = errno;
        sdfc__conn_close(conn);
        errno = saved;
    }
    return rc;
}

void sdfc__conn_close(sdfc__conn *conn)
{
    if (conn->session) {
        gnutls_bye(conn->session, GNUTLS_SHUT_WR); /* once, without waiting */
        gnutls_deinit(conn->session);
        conn->session = NULL;
    }
    if (conn->fd >= 0)
        close(conn->fd);
    conn->fd = -1;
}

/* A GnuTLS failure of a record call in errno's terms (transport.h); errno itself still
 * holds what the socket said when the failure was the socket's. */
static ssize_t tls_errno(const sdfc__conn *conn, ssize_t rc)
{
    int sock = errno;
    if (rc == GNUTLS_E_AGAIN)
        errno = EAGAIN;
    else if (rc == GNUTLS_E_INTERRUPTED || !gnutls_error_is_fatal((int)rc))
        errno = EINTR; /* a warning alert and the like: try again */
    else if (conn->gone || rc == GNUTLS_E_PREMATURE_TERMINATION)
        errno = ECONNRESET;
    else if (rc == GNUTLS_E_PUSH_ERROR || rc == GNUTLS_E_PULL_ERROR)
        errno = sock ? sock : EIO;
    else
        errno = EPROTO;
    return -1;
}

ssize_t sdfc__conn_recv(sdfc__conn *conn, void *buf, size_t len)
{
    if (!conn->session)
        return recv(conn->fd, buf, len, MSG_DONTWAIT);
    errno = 0;
    ssize_t got = gnutls_record_recv(conn->session, buf, len);
    return got >= 0 ? got : tls_errno(conn, got);
}

ssize_t sdfc__conn_send(sdfc__conn *conn, const struct iovec *iov, int iovcnt)
{
    if (!conn->session) {
        struct msghdr m = {.msg_iov = (struct iovec *)iov, .msg_iovlen = (size_t)iovcnt};
        return sendmsg(conn->fd, &m, MSG_NOSIGNAL | MSG_DONTWAIT);
    }
    /* one iovec at a time: a record is at most 16 KiB anyway, and a repeat after EAGAIN
     * must pass GnuTLS the same bytes, which the caller's unchanged iov gives */
    while (iovcnt > 0 && iov->iov_len == 0)
        iov++, iovcnt--;
    if (iovcnt == 0)
        return 0;
    errno = 0;
    ssize_t sent = gnutls_record_send(conn->session, iov->iov_base, iov->iov_len);
    return sent >= 0 ? sent : tls_errno(conn, sent);
}

int sdfc__conn_wait(sdfc__conn *conn, short events, int timeout_ms)
{
    if (conn->session) {
        if ((events & POLLIN) && gnutls_record_check_pending(conn->session) > 0)
            return 1;
        /* a record GnuTLS began to write (EAGAIN) is finished by the next call */
        if (gnutls_record_get_direction(conn->session) == 1)
            events |= POLLOUT;
    }
    return poll_fd(conn->fd, events, timeout_ms);
}
