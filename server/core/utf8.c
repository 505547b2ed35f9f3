/* utf8.c - validation and cleaning of client text (utf8.h). */
#include "core/utf8.h"

#include <string.h>

static int continuation(unsigned char c)
{
    return (c & 0xC0) == 0x80;
}

size_t sdfd_utf8_sequence(const unsigned char *s)
{
    unsigned char c = s[0];
    if (c >= 0x01 && c < 0x80)
        return 1;
    if (c >= 0xC2 && c <= 0xDF)
        return continuation(s[1]) ? 2 : 0;
    if (c >= 0xE0 && c <= 0xEF) {
        unsigned char lo = c == 0xE0 ? 0xA0 : 0x80, hi = c == 0xED ? 0x9F : 0xBF;
        return s[1] >= lo && s[1] <= hi && continuation(s[2]) ? 3 : 0;
    }
    if (c >= 0xF0 && c <= 0xF4) {
        unsigned char lo = c == 0xF0 ? 0x90 : 0x80, hi = c == 0xF4 ? 0x8F : 0xBF;
        return s[1] >= lo && s[1] <= hi && continuation(s[2]) && continuation(s[3]) ? 4 : 0;
    }
    return 0;
}

size_t sdfd_utf8_clean(char *dst, size_t cap, const char *src)
{
    static const char replacement[] = "\xEF\xBF\xBD";
    const unsigned char *s = (const unsigned char *)src;
    size_t len = 0;
    while (*s) {
        size_t n = sdfd_utf8_sequence(s);
        const char *from = n ? (const char *)s : replacement;
        size_t take = n ? n : 3;
        if (len + take >= cap)
            break;
        memcpy(dst + len, from, take);
        len += take;
        s += n ? n : 1;
    }
    dst[len] = '\0';
    return len;
}
