/* tls.c - the certificate and key both front ends serve with (tls.h), and their reload.
 *
 * Every reading of the two files is one sdfd_tls_cert, kept in a list from oldest to newest;
 * the newest is the current one, which new handshakes use. A reload that fails leaves the
 * list as it was. A replaced certificate is freed once nothing can still use it: GnuTLS
 * does not copy what a handshake was given (neither the binary side's credentials nor what
 * MHD's certificate callback returns), so it must outlive the sessions that took it.
 *
 * The binary front end's sessions each hold their certificate (`sessions`). MHD's do not tell
 * us which certificate they took, only when a connection opens and closes; a connection
 * opened while certificate g was current can be handshaken with g or any later one. So each
 * certificate counts the HTTP connections opened while it was current (`http_open`), and a
 * replaced certificate g is freed when no binary session holds it and no HTTP connection
 * opened under g or an older one is still open. */
#include "transport/tls.h"

#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <gnutls/x509.h>

#include "core/log.h"

#define MAX_FILE_BYTES (1u << 20) /* a PEM certificate chain or key is a few KiB */
#define MAX_CHAIN 16              /* certificates in --tls-cert: the server's and its CAs' */

struct sdfd_tls_cert {
    sdfd_tls_cert *next;                    /* the next newer one */
    gnutls_certificate_credentials_t cred;  /* the binary front end's sessions */
    gnutls_pcert_st chain[MAX_CHAIN];       /* MHD's, through sdfd_tls_retrieve */
    unsigned chain_len;
    gnutls_privkey_t key;
    size_t sessions;                        /* binary sessions begun with it, not ended */
    size_t http_open;                       /* HTTP connections opened while it was current */
};

struct sdfd_tls {
    const char *cert_path, *key_path;
    gnutls_priority_t priority;
    pthread_mutex_t lock; /* the list and its counts: MHD's threads, the binary thread, main */
    sdfd_tls_cert *oldest, *current;
};

/* GnuTLS calls sdfd_tls_retrieve with the session only. */
static sdfd_tls *the_tls;

static int read_file(const char *path, const char *what, gnutls_datum_t *out, char *err,
                     size_t cap)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    if (fd < 0 || fstat(fd, &st)) {
        snprintf(err, cap, "%s %s: %s", what, path, strerror(errno));
        if (fd >= 0)
            close(fd);
        return -1;
    }
    if (!S_ISREG(st.st_mode) || st.st_size <= 0 || st.st_size > MAX_FILE_BYTES) {
        snprintf(err, cap, "%s %s: not a regular file of 1 to %u bytes", what, path,
                 MAX_FILE_BYTES);
        close(fd);
        return -1;
    }
    size_t n = (size_t)st.st_size, got = 0;
    unsigned char *data = malloc(n + 1);
    while (data && got < n) {
        ssize_t r = read(fd, data + got, n - got);
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    close(fd);
    if (!data || got != n) {
        snprintf(err, cap, "%s %s: cannot read it", what, path);
        free(data);
        return -1;
    }
    data[n] = '\0';
    *out = (gnutls_datum_t){data, (unsigned)n};
    return 0;
}

static void free_cert(sdfd_tls_cert *c)
{
    if (!c)
        return;
    for (unsigned i = 0; i < c->chain_len; i++)
        gnutls_pcert_deinit(&c->chain[i]);
    gnutls_privkey_deinit(c->key);
    if (c->cred)
        gnutls_certificate_free_credentials(c->cred);
    free(c);
}

/* The first certificate's serial (hex) and expiry, for the log. */
static void describe(const sdfd_tls_cert *c, char *serial, size_t cap, time_t *expires)
{
    gnutls_x509_crt_t crt;
    unsigned char raw[64];
    size_t n = sizeof raw;
    *serial = '\0', *expires = 0;
    if (gnutls_x509_crt_init(&crt))
        return;
    if (!gnutls_x509_crt_import(crt, &c->chain[0].cert, GNUTLS_X509_FMT_DER) &&
        !gnutls_x509_crt_get_serial(crt, raw, &n)) {
        for (size_t i = 0; i < n && 2 * i + 2 < cap; i++)
            snprintf(serial + 2 * i, 3, "%02x", raw[i]);
        *expires = gnutls_x509_crt_get_expiration_time(crt);
    }
    gnutls_x509_crt_deinit(crt);
}

static int parse(sdfd_tls_cert *c, const char *cert_path, const gnutls_datum_t *cert,
                 const char *key_path, const gnutls_datum_t *key, char *err, size_t cap)
{
    c->chain_len = MAX_CHAIN;
    int rc = gnutls_pcert_list_import_x509_raw(c->chain, &c->chain_len, cert,
                                               GNUTLS_X509_FMT_PEM, 0);
    if (rc < 0) {
        c->chain_len = 0;
        snprintf(err, cap, "--tls-cert %s: %s", cert_path,
                 rc == GNUTLS_E_SHORT_MEMORY_BUFFER ? "more than 16 certificates"
                                                     : gnutls_strerror(rc));
        return -1;
    }
    if ((rc = gnutls_privkey_init(&c->key)) < 0 ||
        (rc = gnutls_privkey_import_x509_raw(c->key, key, GNUTLS_X509_FMT_PEM, NULL, 0)) < 0) {
        snprintf(err, cap, "--tls-key %s: %s", key_path, gnutls_strerror(rc));
        return -1;
    }
    /* GnuTLS checks here that the key is the certificate's. */
    if ((rc = gnutls_certificate_allocate_credentials(&c->cred)) < 0 ||
        (rc = gnutls_certificate_set_x509_key_mem2(c->cred, cert, key, GNUTLS_X509_FMT_PEM,
                                                   NULL, 0)) < 0) {
        if (rc == GNUTLS_E_CERTIFICATE_KEY_MISMATCH)
            snprintf(err, cap, "--tls-key %s is not the key of the certificate in --tls-cert %s",
                     key_path, cert_path);
        else
            snprintf(err, cap, "--tls-cert %s, --tls-key %s: %s", cert_path, key_path,
                     gnutls_strerror(rc));
        return -1;
    }
    return 0;
}

static sdfd_tls_cert *load(const sdfd_tls *tls, char *err, size_t cap)
{
    gnutls_datum_t cert = {NULL, 0}, key = {NULL, 0};
    sdfd_tls_cert *c = NULL;
    if (read_file(tls->cert_path, "--tls-cert", &cert, err, cap) ||
        read_file(tls->key_path, "--tls-key", &key, err, cap))
        goto done;
    c = calloc(1, sizeof *c);
    if (!c) {
        snprintf(err, cap, "out of memory");
        goto done;
    }
    if (parse(c, tls->cert_path, &cert, tls->key_path, &key, err, cap)) {
        free_cert(c);
        c = NULL;
        goto done;
    }
    char serial[130];
    time_t expires;
    describe(c, serial, sizeof serial, &expires);
    struct tm tm;
    char when[32] = "?";
    if (expires > 0 && gmtime_r(&expires, &tm))
        strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", &tm);
    sdfd_log(expires > 0 && expires < time(NULL) ? "warn" : "info", "tls_loaded",
             "%s: serial %s, expires %s%s", tls->cert_path, serial, when,
             expires > 0 && expires < time(NULL) ? " (already expired)" : "");
done:
    if (key.data) /* the key's bytes: not left in freed memory */
        memset(key.data, 0, key.size);
    free(key.data);
    free(cert.data);
    return c;
}

/* Free, from the oldest, every replaced certificate nothing can use any more (see the
 * top of the file). Called with the lock held. */
static void free_unused(sdfd_tls *tls)
{
    size_t open_before = 0; /* HTTP connections opened under this certificate or older */
    for (sdfd_tls_cert **link = &tls->oldest; *link;) {
        sdfd_tls_cert *c = *link;
        open_before += c->http_open;
        if (c != tls->current && c->sessions == 0 && open_before == 0) {
            *link = c->next;
            free_cert(c);
        } else {
            link = &c->next;
        }
    }
}

int sdfd_tls_open(const char *cert_path, const char *key_path, sdfd_tls **out, char *err,
                  size_t err_cap)
{
    if (the_tls) {
        snprintf(err, err_cap, "TLS is already set up");
        return -1;
    }
    sdfd_tls *tls = calloc(1, sizeof *tls);
    if (!tls) {
        snprintf(err, err_cap, "out of memory");
        return -1;
    }
    tls->cert_path = cert_path, tls->key_path = key_path;
    int rc = gnutls_priority_init(&tls->priority, SDFD_TLS_PRIORITIES, NULL);
    if (rc < 0) {
        snprintf(err, err_cap, "GnuTLS priorities %s: %s", SDFD_TLS_PRIORITIES,
                 gnutls_strerror(rc));
        free(tls);
        return -1;
    }
    tls->current = tls->oldest = load(tls, err, err_cap);
    if (!tls->current) {
        gnutls_priority_deinit(tls->priority);
        free(tls);
        return -1;
    }
    pthread_mutex_init(&tls->lock, NULL);
    the_tls = tls;
    *out = tls;
    return 0;
}

int sdfd_tls_reload(sdfd_tls *tls, char *err, size_t err_cap)
{
    sdfd_tls_cert *c = load(tls, err, err_cap);
    if (!c)
        return -1;
    pthread_mutex_lock(&tls->lock);
    tls->current->next = c; /* the current one is always the newest */
    tls->current = c;
    free_unused(tls);
    pthread_mutex_unlock(&tls->lock);
    return 0;
}

void sdfd_tls_destroy(sdfd_tls *tls)
{
    if (!tls)
        return;
    for (sdfd_tls_cert *c = tls->oldest, *next; c; c = next) {
        next = c->next;
        free_cert(c);
    }
    gnutls_priority_deinit(tls->priority);
    pthread_mutex_destroy(&tls->lock);
    if (the_tls == tls)
        the_tls = NULL;
    free(tls);
}

int sdfd_tls_session_begin(sdfd_tls *tls, int fd, gnutls_session_t *session,
                           sdfd_tls_cert **cert)
{
    if (gnutls_init(session, GNUTLS_SERVER | GNUTLS_NONBLOCK) < 0)
        return -1;
    pthread_mutex_lock(&tls->lock);
    sdfd_tls_cert *c = tls->current;
    c->sessions++;
    pthread_mutex_unlock(&tls->lock);
    if (gnutls_priority_set(*session, tls->priority) < 0 ||
        gnutls_credentials_set(*session, GNUTLS_CRD_CERTIFICATE, c->cred) < 0) {
        sdfd_tls_session_end(tls, *session, c);
        return -1;
    }
    gnutls_transport_set_int(*session, fd);
    /* The front end bounds the handshake by --timeout; GnuTLS's own default must not. */
    gnutls_handshake_set_timeout(*session, GNUTLS_INDEFINITE_TIMEOUT);
    *cert = c;
    return 0;
}

void sdfd_tls_session_end(sdfd_tls *tls, gnutls_session_t session, sdfd_tls_cert *cert)
{
    gnutls_deinit(session);
    pthread_mutex_lock(&tls->lock);
    cert->sessions--;
    free_unused(tls);
    pthread_mutex_unlock(&tls->lock);
}

int sdfd_tls_retrieve(gnutls_session_t session, const gnutls_datum_t *req_ca_rdn, int nreqs,
                      const gnutls_pk_algorithm_t *pk_algos, int pk_algos_length,
                      gnutls_pcert_st **pcert, unsigned int *pcert_length,
                      gnutls_privkey_t *pkey)
{
    (void)session, (void)req_ca_rdn, (void)nreqs, (void)pk_algos, (void)pk_algos_length;
    sdfd_tls *tls = the_tls;
    if (!tls)
        return -1;
    pthread_mutex_lock(&tls->lock);
    *pcert = tls->current->chain;
    *pcert_length = tls->current->chain_len;
    *pkey = tls->current->key;
    pthread_mutex_unlock(&tls->lock);
    return 0;
}

void *sdfd_tls_connection_opened(sdfd_tls *tls)
{
    pthread_mutex_lock(&tls->lock);
    sdfd_tls_cert *c = tls->current;
    c->http_open++;
    pthread_mutex_unlock(&tls->lock);
    return c;
}

void sdfd_tls_connection_closed(sdfd_tls *tls, void *token)
{
    sdfd_tls_cert *c = token;
    pthread_mutex_lock(&tls->lock);
    c->http_open--;
    free_unused(tls);
    pthread_mutex_unlock(&tls->lock);
}
