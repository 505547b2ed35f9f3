/* test_body.c - JSON query bodies of a megabyte and more, which server/transport/body.c parses in two
 * halves on two threads, against what one sequential parse must give:
 *  - nested [[x, y, z], ...] and flat [x, y, z, ...] arrays (with uneven whitespace) give
 *    exactly the floats strtod gives for every number, in order;
 *  - a bad point, a syntax error or too many points in the second half give the message a
 *    sequential parse gives: the point's index counted from the start, the byte offset, the
 *    limit;
 *  - a short "points" array followed by a long string full of commas and "],[" (so the
 *    split lands outside the array) still parses, and the keys after it are read;
 *  - JSON replies of 200,000 points, which are printed in two halves on two threads, are
 *    the text one loop over the entries prints (written here independently), for the
 *    gradient and closest-point modes (floats, [x, y, z] arrays and triangle ids). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "transport/body.h"
#include "core/errors.h"
#include "core/numtext.h"

/* Reset at the start of every case, so that a case run alone draws what it draws in the
 * whole run. */
#define RNG_SEED 0x2545f4914f6cdd1dull
static unsigned long long rng = RNG_SEED;
static double next_value(void)
{
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return ((double)(rng >> 11) / 9007199254740992.0 - 0.5) * 200.0;
}

typedef struct text {
    char *s;
    size_t len, cap;
} text;

static void put(text *t, const char *s)
{
    size_t n = strlen(s);
    if (t->len + n + 1 > t->cap) {
        t->cap = 2 * (t->len + n + 1);
        t->s = realloc(t->s, t->cap);
    }
    memcpy(t->s + t->len, s, n + 1);
    t->len += n;
}

enum { GOOD, TWO_NUMBERS, NOT_A_NUMBER };

/* A body of `points` points (nested or flat), its numbers' floats (as the parser's double,
 * rounded to float) in `expect`. Point `bad_point` is spoilt as `bad` says: two numbers
 * only, or a '#' for its first number, whose byte offset goes to *bad_at. */
static text make_body(size_t points, int nested, float *expect, size_t bad_point, int bad,
                      size_t *bad_at)
{
    text t = {0};
    put(&t, "{\"mode\": \"signed\", \"points\": [");
    for (size_t i = 0; i < points; i++) {
        if (i)
            put(&t, i % 7 ? "," : " ,\n ");
        if (nested)
            put(&t, i % 5 ? "[" : "[ ");
        int coords = i == bad_point && bad == TWO_NUMBERS ? 2 : 3;
        for (int k = 0; k < coords; k++) {
            char num[64];
            snprintf(num, sizeof num, "%.9g", next_value());
            if (k)
                put(&t, i % 3 ? "," : ", ");
            if (i == bad_point && bad == NOT_A_NUMBER && k == 0) {
                *bad_at = t.len;
                put(&t, "#");
                continue;
            }
            put(&t, num);
            if (expect)
                expect[3 * i + (size_t)k] = (float)strtod(num, NULL);
        }
        if (nested)
            put(&t, "]");
    }
    put(&t, "], \"sign\": \"auto\"}");
    return t;
}

static int parse(text *t, size_t max_points, float **points, size_t *count, char *err,
                 size_t cap, sdfd_query_params *params)
{
    int owned = 0;
    *params = (sdfd_query_params){0};
    int rc = sdfd_parse_points(SDFD_FORM_JSON, t->s, t->len, max_points, params, points, count,
                               &owned, err, cap);
    if (rc)
        *points = NULL;
    return rc;
}

static void test_valid(int nested)
{
    rng = RNG_SEED;
    size_t n = 200000; /* ~6 MB of text */
    float *expect = malloc(3 * n * sizeof *expect), *got;
    text t = make_body(n, nested, expect, SIZE_MAX, GOOD, NULL);
    CHECK(t.len > ((size_t)1 << 21), "body of %zu bytes is too small to be split", t.len);
    size_t count;
    char err[256];
    sdfd_query_params params;
    int rc = parse(&t, 1000000, &got, &count, err, sizeof err, &params);
    CHECK(rc == 0, "%s: %s", nested ? "nested" : "flat", err);
    if (!rc) {
        CHECK(count == n, "%zu points, expected %zu", count, n);
        CHECK(count == n && !memcmp(got, expect, 3 * n * sizeof *got),
              "%s: parsed floats differ from strtod's", nested ? "nested" : "flat");
        CHECK(params.sign_len == 4 && !memcmp(params.sign, "auto", 4),
              "the key after the points was not read");
        free(got);
    }
    free(t.s), free(expect);
}

static void test_errors(void)
{
    rng = RNG_SEED;
    size_t n = 200000, bad = 170000, count, at = 0;
    char err[256], want[128];
    float *got;
    sdfd_query_params params;
    text t = make_body(n, 1, NULL, bad, TWO_NUMBERS, NULL);
    snprintf(want, sizeof want, "point %zu is not an array of 3 numbers", bad);
    CHECK(parse(&t, 1000000, &got, &count, err, sizeof err, &params) == SDF_EINVAL &&
              !strcmp(err, want),
          "a bad point late in the body: '%s', expected '%s'", err, want);
    free(t.s);

    t = make_body(n, 1, NULL, bad, NOT_A_NUMBER, &at);
    snprintf(want, sizeof want, "malformed JSON at byte %zu: expected a number", at);
    CHECK(parse(&t, 1000000, &got, &count, err, sizeof err, &params) == SDFD_ESYNTAX &&
              !strcmp(err, want),
          "a late syntax error: '%s', expected '%s'", err, want);
    free(t.s);

    t = make_body(n, 0, NULL, SIZE_MAX, GOOD, NULL);
    snprintf(want, sizeof want, "more than %zu points (limit)", n - 1);
    CHECK(parse(&t, n - 1, &got, &count, err, sizeof err, &params) == SDF_ELIMIT &&
              !strcmp(err, want),
          "halves over the limit together: '%s', expected '%s'", err, want);
    free(t.s);
}

/* JSON numbers beyond float32's range are refused as such, not turned into infinities
 * (which the batcher would then call NaN or Inf); the largest float and numbers that
 * round down to it or to zero are fine. */
static void test_float_range(void)
{
    rng = RNG_SEED;
    static const struct {
        const char *body;
        int rc;
        const char *says;
    } cases[] = {
        {"{\"points\": [[0, 0, 0], [1, 1e39, 0]]}", SDF_ENONFINITE,
         "point 1: coordinate 1e+39 is beyond float32's range"},
        {"{\"points\": [0, 0, 0, 1, 2, -3.5e38]}", SDF_ENONFINITE,
         "point 1: coordinate -3.5e+38 is beyond float32's range"},
        {"{\"points\": [[3.4028234e38, -3.4028234e38, 1e-50]]}", 0, ""},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        text t = {0};
        put(&t, cases[i].body);
        float *got;
        size_t count;
        char err[256] = "";
        sdfd_query_params params;
        int rc = parse(&t, 10, &got, &count, err, sizeof err, &params);
        CHECK(rc == cases[i].rc && strstr(err, cases[i].says), "%s: %d '%s'", cases[i].body,
              rc, err);
        if (!rc) {
            CHECK(count == 1 && got[0] == 3.4028234e38f && got[2] == 0, "largest float");
            free(got);
        }
        free(t.s);
    }
}

/* The split lands in a long string after a short array. */
static void test_split_outside(void)
{
    rng = RNG_SEED;
    text t = {0};
    put(&t, "{\"points\": [[1, 2, 3], [4, 5, 6]], \"note\": \"");
    while (t.len < ((size_t)3 << 20))
        put(&t, "],[1,2,3],[ , ");
    put(&t, "\", \"mode\": \"distance\"}");
    float *got;
    size_t count;
    char err[256];
    sdfd_query_params params;
    int rc = parse(&t, 1000, &got, &count, err, sizeof err, &params);
    CHECK(rc == 0, "short array, long string after it: %s", err);
    if (!rc) {
        float expect[6] = {1, 2, 3, 4, 5, 6};
        CHECK(count == 2 && !memcmp(got, expect, sizeof expect), "got %zu points", count);
        CHECK(params.mode_len == 8 && !memcmp(params.mode, "distance", 8), "mode not read");
        free(got);
    }
    free(t.s);
}

/* The reply's JSON against one plain loop: {"distance":[..],"gradient"|"closest":[[..]..]
 * (,"triangle":[..])}. */
static void test_reply(sdf_proto_mode mode)
{
    rng = RNG_SEED;
    size_t n = 200000;
    unsigned w = sdf_proto_words(mode);
    sdfd_reply r;
    CHECK(sdfd_reply_init(&r, SDFD_FORM_JSON, mode, n, NULL, 0) == 0, "reply_init");
    for (size_t i = 0; i < n * w; i++) {
        float f = (float)next_value() * (i % 11 ? 1.0f : 1e-6f);
        if (i % 1000 == 7)
            f = i % 2000 == 7 ? 0.0f : -0.0f;
        memcpy(&r.words[i], &f, 4);
        if (mode == SDF_MODE_CLOSEST && i % w == 4)
            r.words[i] = (uint32_t)(rng % 100000);
    }
    text want = {0};
    char num[64];
    put(&want, "{\"distance\":[");
    for (size_t i = 0; i < n; i++) {
        float f;
        memcpy(&f, &r.words[w * i], 4);
        num[sdfd_format_float(f, num)] = '\0';
        put(&want, i ? "," : "");
        put(&want, num);
    }
    put(&want, mode == SDF_MODE_CLOSEST ? "],\"closest\":[" : "],\"gradient\":[");
    for (size_t i = 0; i < n; i++) {
        put(&want, i ? ",[" : "[");
        for (unsigned k = 1; k <= 3; k++) {
            float f;
            memcpy(&f, &r.words[w * i + k], 4);
            num[sdfd_format_float(f, num)] = '\0';
            put(&want, k > 1 ? "," : "");
            put(&want, num);
        }
        put(&want, "]");
    }
    if (mode == SDF_MODE_CLOSEST) {
        put(&want, "],\"triangle\":[");
        for (size_t i = 0; i < n; i++) {
            snprintf(num, sizeof num, "%s%u", i ? "," : "", r.words[w * i + 4]);
            put(&want, num);
        }
    }
    put(&want, "]}");
    size_t len = 0;
    char *got = sdfd_reply_render(&r, SDFD_FORM_JSON, &len);
    CHECK(got && len == want.len && !memcmp(got, want.s, len),
          "mode %d: the reply's JSON (%zu bytes) differs from one loop's (%zu bytes)", (int)mode,
          len, want.len);
    free(got), free(want.s), free(r.buffer);
}

static void test_valid_nested(void)
{
    test_valid(1);
}

static void test_valid_flat(void)
{
    test_valid(0);
}

static void test_reply_gradient(void)
{
    test_reply(SDF_MODE_GRADIENT);
}

static void test_reply_closest(void)
{
    test_reply(SDF_MODE_CLOSEST);
}

static const check_case cases[] = {
    {"valid_nested", test_valid_nested},
    {"valid_flat", test_valid_flat},
    {"errors", test_errors},
    {"split_outside", test_split_outside},
    {"float_range", test_float_range},
    {"reply_gradient", test_reply_gradient},
    {"reply_closest", test_reply_closest},
};

int main(int argc, char **argv)
{
    return check_main("body", cases, CHECK_COUNT_OF(cases), argc, argv);
}
