/* text.c - strict number/token scanning with line counting (see text.h). */
#include "mesh/text.h"

#include <stdlib.h>
#include <string.h>

static int is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

void sdf__text_init(sdf__text *t, const char *buf, size_t len)
{
    t->begin = t->p = buf;
    t->end = buf + len;
    t->line = 1;
}

int sdf__text_eof(const sdf__text *t) { return t->p >= t->end; }

long long sdf__text_offset(const sdf__text *t) { return (long long)(t->p - t->begin); }

void sdf__text_skip_blanks(sdf__text *t)
{
    while (t->p < t->end && is_blank(*t->p))
        t->p++;
}

void sdf__text_skip_space(sdf__text *t)
{
    while (t->p < t->end && (is_blank(*t->p) || *t->p == '\n')) {
        if (*t->p == '\n')
            t->line++;
        t->p++;
    }
}

void sdf__text_next_line(sdf__text *t)
{
    const char *nl = memchr(t->p, '\n', (size_t)(t->end - t->p));
    if (!nl) {
        t->p = t->end;
        return;
    }
    t->p = nl + 1;
    t->line++;
}

int sdf__text_at_eol(sdf__text *t)
{
    sdf__text_skip_blanks(t);
    return t->p >= t->end || *t->p == '\n';
}

static size_t scan_token(sdf__text *t, const char **start)
{
    *start = t->p;
    while (t->p < t->end && !is_blank(*t->p) && *t->p != '\n')
        t->p++;
    return (size_t)(t->p - *start);
}

size_t sdf__text_token(sdf__text *t, const char **start)
{
    sdf__text_skip_blanks(t);
    return scan_token(t, start);
}

size_t sdf__text_token_any_line(sdf__text *t, const char **start)
{
    sdf__text_skip_space(t);
    return scan_token(t, start);
}

int sdf__text_token_is(const char *s, size_t n, const char *word)
{
    return strlen(word) == n && memcmp(s, word, n) == 0;
}

/* Position the cursor on the next number's first character. */
static int seek_number(sdf__text *t, int any_line)
{
    if (any_line)
        sdf__text_skip_space(t);
    else
        sdf__text_skip_blanks(t);
    if (t->p >= t->end || *t->p == '\n')
        return SDF__TEXT_MISSING;
    return SDF__TEXT_OK;
}

static int delimited(const sdf__text *t, const char *q, char delim)
{
    return q >= t->end || is_blank(*q) || *q == '\n' || (delim && *q == delim);
}

int sdf__text_double(sdf__text *t, double *out, int any_line)
{
    int rc = seek_number(t, any_line);
    if (rc)
        return rc;
    char *q;
    *out = strtod(t->p, &q);
    if (q == t->p || !delimited(t, q, 0))
        return SDF__TEXT_MALFORMED;
    t->p = q;
    return SDF__TEXT_OK;
}

int sdf__text_integer(sdf__text *t, long long *out, int any_line, char delim)
{
    int rc = seek_number(t, any_line);
    if (rc)
        return rc;
    char *q;
    *out = strtoll(t->p, &q, 10);
    if (q == t->p || !delimited(t, q, delim))
        return SDF__TEXT_MALFORMED;
    t->p = q;
    return SDF__TEXT_OK;
}
