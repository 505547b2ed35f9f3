/* test_utf8.c - server/core/utf8.c, which keeps client bytes quoted in error messages and log
 * lines valid UTF-8: every valid sequence passes unchanged (all lengths, the boundaries of
 * RFC 3629's table), every invalid byte becomes U+FFFD (overlong forms, surrogates, past
 * U+10FFFF, lone continuation bytes, a sequence cut short), and the output never cuts a
 * character at its buffer's end. */
#include <string.h>

#include "../common/check.h"
#include "core/utf8.h"

static void valid_sequences(void)
{
    static const char *const valid[] = {"a", "\xC2\x80", "\xDF\xBF", "\xE0\xA0\x80", "\xED\x9F\xBF",
                                        "\xEE\x80\x80", "\xEF\xBF\xBF", "\xF0\x90\x80\x80",
                                        "\xF4\x8F\xBF\xBF"};
    for (size_t i = 0; i < CHECK_COUNT_OF(valid); i++) {
        size_t n = strlen(valid[i]);
        CHECK(sdfd_utf8_sequence((const unsigned char *)valid[i]) == n, "valid %zu", i);
        char out[16];
        CHECK(sdfd_utf8_clean(out, sizeof out, valid[i]) == n && !strcmp(out, valid[i]),
              "valid %zu is kept", i);
    }
}

static void invalid_bytes(void)
{
    static const char *const invalid[] = {"\x80", "\xBF", "\xC0\x80", "\xC1\xBF", "\xE0\x9F\xBF",
                                          "\xED\xA0\x80", "\xF0\x8F\xBF\xBF", "\xF4\x90\x80\x80",
                                          "\xF5\x80\x80\x80", "\xFF", "\xE2\x82", "\xF0\x90\x80"};
    for (size_t i = 0; i < CHECK_COUNT_OF(invalid); i++) {
        CHECK(sdfd_utf8_sequence((const unsigned char *)invalid[i]) == 0, "invalid %zu", i);
        char out[64];
        size_t n = sdfd_utf8_clean(out, sizeof out, invalid[i]);
        CHECK(n >= 3 && !memcmp(out, "\xEF\xBF\xBD", 3), "invalid %zu starts with U+FFFD", i);
        for (size_t at = 0; at < n;) { /* and all of it is valid */
            size_t k = sdfd_utf8_sequence((const unsigned char *)out + at);
            CHECK(k > 0, "invalid %zu: the output is valid at %zu", i, at);
            at += k ? k : n;
        }
    }
    char out[32];
    CHECK(sdfd_utf8_clean(out, sizeof out, "\xffrder") == 7 && !strcmp(out, "\xEF\xBF\xBDrder"),
          "a key with a stray byte");
}

static void cut_at_characters(void)
{
    char out[5];
    CHECK(sdfd_utf8_clean(out, sizeof out, "ab\xE2\x82\xAC") == 2 && !strcmp(out, "ab"),
          "a euro sign that does not fit is left out whole");
    CHECK(sdfd_utf8_clean(out, 1, "abc") == 0 && out[0] == '\0', "room for the NUL alone");
    CHECK(sdfd_utf8_clean(out, sizeof out, "") == 0 && out[0] == '\0', "empty");
}

int main(int argc, char **argv)
{
    static const check_case cases[] = {
        {"valid_sequences", valid_sequences},
        {"invalid_bytes", invalid_bytes},
        {"cut_at_characters", cut_at_characters},
    };
    return check_main("test_utf8", cases, CHECK_COUNT_OF(cases), argc, argv);
}
