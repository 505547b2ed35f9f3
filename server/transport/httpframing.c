/* httpframing.c - the framing check of httpframing.h. A proxy in front of sdfd and
 * libmicrohttpd must agree on where a request ends, or the bytes one of them takes for a body
 * the other takes for the next request (request smuggling). libmicrohttpd 0.9.75 reads these
 * requests one way without complaint, so they are refused here, 400 ESYNTAX:
 *  - two Content-Length fields with different values: it takes the first;
 *  - Content-Length with Transfer-Encoding: it decodes the chunks and ignores the length
 *    (RFC 9112 section 6.3 lets a server refuse such a request, and it must close after it);
 *  - white space between a field name and its colon ("Transfer-Encoding : chunked"), which
 *    RFC 9112 section 5.1 says a server must refuse: it keeps the space in the name, so the
 *    field frames nothing for it though it may for a lenient proxy.
 * Two Content-Length fields with the same value are one length (RFC 9110 section 8.6), and a
 * Content-Length that is not one number ("12, 24", "ab") libmicrohttpd refuses itself with its
 * own 400 and closes the connection. */
#include "transport/httpframing.h"

#include <microhttpd.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "core/errors.h"

typedef struct fields {
    const char *length;      /* the first Content-Length's value, or NULL */
    size_t length_size;
    const char *other;       /* a later Content-Length's different value, or NULL */
    size_t other_size;
    int transfer_encoding;   /* a Transfer-Encoding field is present */
    char spaced[72];         /* the first field name with white space in it, or "" */
} fields;

static int named(const char *key, size_t n, const char *name)
{
    return n == strlen(name) && !strncasecmp(key, name, n);
}

/* `s` (n bytes) as printable text for a message: at most 64 bytes, controls as '?'. */
static void printable(char *out, size_t cap, const char *s, size_t n)
{
    size_t k = 0;
    for (; k < n && k < 64 && k + 1 < cap; k++)
        out[k] = s[k] >= 0x20 && s[k] < 0x7f ? s[k] : '?';
    out[k] = '\0';
}

static enum MHD_Result look(void *cls, enum MHD_ValueKind kind, const char *key, size_t key_size,
                            const char *value, size_t value_size)
{
    fields *f = cls;
    (void)kind;
    if (!value)
        value = "", value_size = 0;
    if (!f->spaced[0] && (memchr(key, ' ', key_size) || memchr(key, '\t', key_size)))
        printable(f->spaced, sizeof f->spaced, key, key_size);
    if (named(key, key_size, MHD_HTTP_HEADER_CONTENT_LENGTH)) {
        if (!f->length)
            f->length = value, f->length_size = value_size;
        else if (!f->other && (value_size != f->length_size || memcmp(value, f->length, value_size)))
            f->other = value, f->other_size = value_size;
    }
    if (named(key, key_size, MHD_HTTP_HEADER_TRANSFER_ENCODING))
        f->transfer_encoding = 1;
    return MHD_YES;
}

int sdfd_http_framing_check(struct MHD_Connection *conn, char *err, size_t cap)
{
    fields f = {.length = NULL};
    MHD_get_connection_values_n(conn, MHD_HEADER_KIND, look, &f);
    char a[72], b[72];
    if (f.spaced[0]) {
        snprintf(err, cap, "white space between the header field name '%s' and its colon: "
                 "the field names nothing (RFC 9112 section 5.1)", f.spaced);
        return SDFD_ESYNTAX;
    }
    if (f.other) {
        printable(a, sizeof a, f.length, f.length_size);
        printable(b, sizeof b, f.other, f.other_size);
        snprintf(err, cap, "Content-Length is given twice, as %s and as %s: where the body "
                 "ends is ambiguous (RFC 9112 section 6.3)", a, b);
        return SDFD_ESYNTAX;
    }
    if (f.length && f.transfer_encoding) {
        snprintf(err, cap, "both Content-Length and Transfer-Encoding are given: where the body "
                 "ends is ambiguous (RFC 9112 section 6.3); send Content-Length alone");
        return SDFD_ESYNTAX;
    }
    return 0;
}
