/* utf8.h - text from clients made safe to put in JSON and in protocol messages. An error
 * message often quotes what a client sent (a key, a name, a URL argument), and JSON and the
 * binary protocol's messages are UTF-8: a byte that does not belong to a valid sequence would
 * make the whole answer unreadable, so it is replaced by U+FFFD. Pure functions. */
#ifndef SDFD_UTF8_H
#define SDFD_UTF8_H

#include <stddef.h>

/* The length (1-4) of the valid UTF-8 sequence that begins at s, or 0 when none does (RFC
 * 3629: no overlong forms, no surrogates, nothing past U+10FFFF, no NUL). Reads at most up
 * to the first NUL. */
size_t sdfd_utf8_sequence(const unsigned char *s);

/* Copy the NUL-terminated src into dst (cap >= 1 bytes, always NUL-terminated), each byte
 * that begins no valid sequence replaced by U+FFFD, and never cutting a character: returns
 * the length written. */
size_t sdfd_utf8_clean(char *dst, size_t cap, const char *src);

#endif
