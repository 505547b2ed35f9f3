/* httpframing.h - where an HTTP request's body ends, checked from its headers alone (RFC 9112
 * section 6.3) before any body byte is read: a request that two HTTP parsers could frame two
 * ways is refused (httpframing.c says which, and what libmicrohttpd refuses itself). */
#ifndef SDFD_HTTPFRAMING_H
#define SDFD_HTTPFRAMING_H

#include <stddef.h>

struct MHD_Connection;

/* Look at the request's header fields on `conn` (their first callback: the headers are all
 * in). Returns 0 when its framing is unambiguous; SDFD_ESYNTAX, with a one-line reason in
 * `err` (`cap` bytes, NUL-terminated), when Content-Length is given with two different values,
 * when Content-Length and Transfer-Encoding are both given, or when a field name has white
 * space before its colon. The caller answers 400 at once; libmicrohttpd closes a connection
 * answered before its body is read, so no byte after the headers is taken for a request.
 * Reads only; called on the connection's libmicrohttpd thread. */
int sdfd_http_framing_check(struct MHD_Connection *conn, char *err, size_t cap);

#endif
