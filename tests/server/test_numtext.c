/* test_numtext.c - the JSON number fast paths (server/core/numtext.c) against the C library:
 *  - every printed float reads back as the same float, through strtof and through strtod
 *    and a cast (as Python's json + numpy do), for 2,000,000 random bit patterns and the
 *    edge values; the text is valid JSON and within SDFD_FLOAT_TEXT_MAX;
 *  - every parsed number is the double strtod gives, ending where strtod ends, for numbers
 *    printed in many formats and for hand-picked hard cases. */
#include <inttypes.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "core/numtext.h"

/* Reset at the start of every case, so that a case run alone draws what it draws in the
 * whole run. */
#define RNG_SEED 0x9e3779b97f4a7c15u
static uint64_t rng = RNG_SEED;
static uint64_t next(void)
{
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return rng;
}

static int json_number_grammar(const char *s)
{
    const char *p = s;
    p += *p == '-';
    if (*p == '0')
        p++;
    else if (*p >= '1' && *p <= '9')
        while (*p >= '0' && *p <= '9')
            p++;
    else
        return 0;
    if (*p == '.') {
        p++;
        if (!(*p >= '0' && *p <= '9'))
            return 0;
        while (*p >= '0' && *p <= '9')
            p++;
    }
    if (*p == 'e' || *p == 'E') {
        p++;
        p += *p == '+' || *p == '-';
        if (!(*p >= '0' && *p <= '9'))
            return 0;
        while (*p >= '0' && *p <= '9')
            p++;
    }
    return *p == 0;
}

static void check_float(float f)
{
    char text[SDFD_FLOAT_TEXT_MAX + 8];
    memset(text, 'x', sizeof text);
    size_t n = sdfd_format_float(f, text);
    CHECK(n <= SDFD_FLOAT_TEXT_MAX, "%a: %zu characters", (double)f, n);
    text[n] = 0;
    float back = strtof(text, NULL), via_double = (float)strtod(text, NULL);
    CHECK(!memcmp(&back, &f, 4) && !memcmp(&via_double, &f, 4),
          "%a printed as %s reads back as %a / %a", (double)f, text, (double)back,
          (double)via_double);
    CHECK(json_number_grammar(text), "%s is not a JSON number", text);
}

static void test_format(void)
{
    rng = RNG_SEED;
    const float edges[] = {0.0f, -0.0f, 1.0f, -1.0f, 0.1f, 1e-4f, 9.99999e-5f, 1e-5f, 123456789.0f,
                           999999999.0f, 1e9f, 3.4028235e38f, -3.4028235e38f, 1.17549435e-38f,
                           1.4e-45f, 1e-45f, 0.3f, 2.5f, 100.0f, 1e8f};
    for (size_t i = 0; i < sizeof edges / sizeof edges[0]; i++)
        check_float(edges[i]);
    int failures = check_failures;
    for (int i = 0; i < 2000000 && check_failures - failures < 5; i++) {
        uint32_t bits = (uint32_t)next();
        float f;
        memcpy(&f, &bits, 4);
        if (isfinite(f))
            check_float(f);
    }
    /* Typical distances: small magnitudes with all digits. */
    for (int i = 0; i < 200000 && check_failures - failures < 5; i++)
        check_float((float)((double)(next() % 2000001) / 1e6 - 1.0));
}

static void check_parse(const char *text)
{
    double fast, slow;
    const char *end_fast = sdfd_parse_number(text, &fast);
    char *end_slow;
    slow = strtod(text, &end_slow);
    CHECK(end_fast == end_slow && !memcmp(&fast, &slow, sizeof fast),
          "\"%s\": %a ending at %td, strtod %a ending at %td", text, fast, end_fast - text, slow,
          end_slow - text);
}

static void test_parse(void)
{
    rng = RNG_SEED;
    const char *hard[] = {"0", "-0", "0.0", "1", "-1", "1e22", "1e23", "1e-22", "1e-23",
                          "9007199254740992", "9007199254740993", "9007199254740993.0",
                          "123456789012345678901234", "0.000000000000000000000001",
                          "1234567890123456789", "12345678901234567890", "1.", "1e", "1e+",
                          "1e-", "01", "-01.5", "1.5e-300", "1e400", "-1e400", "4.9e-324",
                          "2.2250738585072014e-308", "0.1", "0.30000000000000004",
                          "3.4028235e38", "1E5", "1e+05", "7.038531e-26", "1e10000000000"};
    for (size_t i = 0; i < sizeof hard / sizeof hard[0]; i++)
        check_parse(hard[i]);
    const char *formats[] = {"%.1g", "%.3g", "%.6g", "%.9g", "%.12g", "%.15g", "%.17g",
                             "%.0f", "%.3f", "%.7f", "%.10f", "%e", "%.3e", "%.16e"};
    char text[512];
    int failures = check_failures;
    for (int i = 0; i < 300000 && check_failures - failures < 5; i++) {
        uint64_t bits = next();
        double v;
        if (i % 2) { /* any double */
            memcpy(&v, &bits, sizeof v);
            if (!isfinite(v))
                continue;
        } else { /* coordinates of everyday size */
            v = ((double)(bits >> 11) / 9007199254740992.0 - 0.5) * pow(10, (int)(bits % 9) - 4);
        }
        snprintf(text, sizeof text, formats[next() % (sizeof formats / sizeof formats[0])], v);
        strcat(text, ",");
        check_parse(text);
    }
}

/* Long mantissas (16-19 digits) with exponents within +-19, which take the 128-bit path,
 * and floats printed as Python's json prints them (17 digits, via a double). */
static void test_parse_long(void)
{
    rng = RNG_SEED;
    char text[64];
    int failures = check_failures;
    for (int i = 0; i < 1000000 && check_failures - failures < 5; i++) {
        uint64_t m = next(), digits = 16 + next() % 4;
        uint64_t limit = 1;
        for (uint64_t d = 0; d < digits; d++)
            limit *= 10;
        m %= limit;
        int e = (int)(next() % 39) - 19;
        if (i % 3 == 0) {
            snprintf(text, sizeof text, "%" PRIu64 "e%d,", m, e);
        } else if (i % 3 == 1) { /* a decimal point inside the digits */
            int n = snprintf(text, sizeof text, "%" PRIu64, m), at = 1 + (int)(next() % (uint64_t)n);
            memmove(text + at + 1, text + at, (size_t)(n - at + 1));
            text[at] = '.';
            strcat(text, "]");
        } else {
            uint32_t bits = (uint32_t)next();
            float f;
            memcpy(&f, &bits, sizeof f);
            if (!isfinite(f))
                continue;
            snprintf(text, sizeof text, "%.17g}", (double)f);
        }
        check_parse(text);
    }
}

/* JSON has no Inf or NaN: they come out null (the formatter used to loop forever on them). */
static void test_format_nonfinite(void)
{
    rng = RNG_SEED;
    const float odd[] = {INFINITY, -INFINITY, NAN, -NAN};
    for (size_t i = 0; i < sizeof odd / sizeof *odd; i++) {
        char text[SDFD_FLOAT_TEXT_MAX + 1];
        size_t n = sdfd_format_float(odd[i], text);
        text[n] = 0;
        CHECK(!strcmp(text, "null"), "%g written as '%s'", (double)odd[i], text);
    }
}

static const check_case cases[] = {
    {"format", test_format},
    {"format_nonfinite", test_format_nonfinite},
    {"parse", test_parse},
    {"parse_long", test_parse_long},
};

int main(int argc, char **argv)
{
    return check_main("numtext", cases, CHECK_COUNT_OF(cases), argc, argv);
}
