/* text.h - a cursor over a text mesh file for the OBJ, OFF, ASCII PLY and ASCII STL parsers.
 *
 * The buffer must hold a NUL after its last byte (loaders guarantee it), so strtod/strtoll
 * can never read past the end. Numbers are parsed strictly: the text after a number must be
 * whitespace, the end, or a caller-named delimiter ('/' in OBJ faces), so "3.1+e2" is an
 * error rather than a silent 3.1. The cursor counts lines for error messages. */
#ifndef SDF_MESH_TEXT_H
#define SDF_MESH_TEXT_H

#include <stddef.h>

typedef struct sdf__text {
    const char *begin, *p, *end; /* *end == '\0' */
    long line;                   /* 1-based line of p */
} sdf__text;

enum { SDF__TEXT_OK = 0, SDF__TEXT_MISSING = -1, SDF__TEXT_MALFORMED = -2 };

void sdf__text_init(sdf__text *t, const char *buf, size_t len);
int sdf__text_eof(const sdf__text *t);
long long sdf__text_offset(const sdf__text *t);

/* Skip spaces, tabs and CRs on the current line. */
void sdf__text_skip_blanks(sdf__text *t);
/* Skip all whitespace including newlines (counting them). */
void sdf__text_skip_space(sdf__text *t);
/* Move to the start of the next line. */
void sdf__text_next_line(sdf__text *t);
/* After skipping blanks: is the cursor at a newline or the end? */
int sdf__text_at_eol(sdf__text *t);

/* The next whitespace-delimited token on the current line; returns its length (0 at end of
 * line) and sets *start. */
size_t sdf__text_token(sdf__text *t, const char **start);
/* As sdf__text_token, but may cross newlines. */
size_t sdf__text_token_any_line(sdf__text *t, const char **start);
/* Does the token [s, s+n) equal the NUL-terminated `word`? (case-sensitive) */
int sdf__text_token_is(const char *s, size_t n, const char *word);

/* Parse the next number on the current line (`any_line`: or on a later line). Returns
 * SDF__TEXT_OK, SDF__TEXT_MISSING (end of line / file) or SDF__TEXT_MALFORMED. */
int sdf__text_double(sdf__text *t, double *out, int any_line);
/* An integer; `delim` is an extra character allowed to end it (0 for none). */
int sdf__text_integer(sdf__text *t, long long *out, int any_line, char delim);

#endif
