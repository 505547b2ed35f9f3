/* numtext.c - decimal text <-> numbers for the JSON body (see numtext.h). */
#include "core/numtext.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* 10^0 .. 10^22: every one is exact in a double. */
static const double exact_pow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                       1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                       1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/* 10^0 .. 10^19: every one fits 64 bits. */
static const uint64_t pow10_u64[20] = {
    1u, 10u, 100u, 1000u, 10000u, 100000u, 1000000u, 10000000u, 100000000u, 1000000000u,
    UINT64_C(10000000000), UINT64_C(100000000000), UINT64_C(1000000000000),
    UINT64_C(10000000000000), UINT64_C(100000000000000), UINT64_C(1000000000000000),
    UINT64_C(10000000000000000), UINT64_C(100000000000000000),
    UINT64_C(1000000000000000000), UINT64_C(10000000000000000000)};

__extension__ typedef unsigned __int128 u128;

static int digit(char c) { return c >= '0' && c <= '9'; }

/* m * 10^exp10 correctly rounded (to nearest, ties to even), for 0 < m < 2^64 and |exp10|
 * <= 19: the digits Clinger's path cannot take, such as the 17 significant digits that
 * Python's json writes for every float. Exact integer arithmetic on 128 bits: the product,
 * or the quotient of m (shifted to the top of 128 bits) by 10^-exp10 with the remainder as
 * a sticky bit, then rounded once to 53 bits. The results lie in [1e-19, 2e38], where
 * doubles are normal, so scaling by a power of two is exact. */
static double scale_exact(uint64_t m, int exp10)
{
    u128 q;
    int sticky = 0, shift = 0; /* value = (q + sticky fraction) * 2^shift */
    if (exp10 >= 0) {
        q = (u128)m * pow10_u64[exp10];
    } else {
        int lz = __builtin_clzll(m);
        u128 num = (u128)(m << lz) << 64;
        uint64_t d = pow10_u64[-exp10];
        q = num / d;
        sticky = num - q * d != 0;
        shift = -(64 + lz);
    }
    uint64_t hi = (uint64_t)(q >> 64);
    int bits = hi ? 128 - __builtin_clzll(hi) : 64 - __builtin_clzll((uint64_t)q);
    if (bits <= 53) /* exact (only products get here) */
        return ldexp((double)(uint64_t)q, shift);
    int drop = bits - 53;
    uint64_t top = (uint64_t)(q >> drop);
    u128 rest = q & (((u128)1 << drop) - 1), half = (u128)1 << (drop - 1);
    if (rest > half || (rest == half && (sticky || (top & 1))))
        top++;
    return ldexp((double)top, drop + shift); /* top == 2^53 after a carry is still exact */
}

const char *sdfd_parse_number(const char *s, double *value)
{
    const char *p = s;
    int negative = *p == '-';
    p += negative;
    uint64_t mantissa = 0;
    int digits = 0, exp10 = 0; /* significant digits kept; value = mantissa * 10^exp10 */
    if (!digit(*p))
        goto slow;
    for (; digit(*p); p++) {
        if (digits || *p != '0') {
            if (++digits > 19)
                goto slow;
            mantissa = mantissa * 10 + (uint64_t)(*p - '0');
        }
    }
    if (*p == '.') {
        p++;
        if (!digit(*p))
            goto slow; /* "1." : strtod's business */
        for (; digit(*p); p++) {
            if (digits || *p != '0') {
                if (++digits > 19)
                    goto slow;
                mantissa = mantissa * 10 + (uint64_t)(*p - '0');
            }
            exp10--;
        }
    }
    if (*p == 'e' || *p == 'E') {
        const char *e = p + 1;
        int eneg = *e == '-';
        e += *e == '-' || *e == '+';
        if (!digit(*e))
            goto slow;
        int ev = 0;
        for (; digit(*e); e++) {
            if (ev > 10000)
                goto slow;
            ev = ev * 10 + (*e - '0');
        }
        exp10 += eneg ? -ev : ev;
        p = e;
    }
    double v;
    if (mantissa <= (UINT64_C(1) << 53) && exp10 >= -22 && exp10 <= 22) {
        /* Both operands exact, so the one rounding is IEEE's: the correctly rounded result. */
        v = (double)mantissa;
        v = exp10 < 0 ? v / exact_pow10[-exp10] : v * exact_pow10[exp10];
    } else if (mantissa && exp10 >= -19 && exp10 <= 19) {
        v = scale_exact(mantissa, exp10);
    } else {
        goto slow;
    }
    *value = negative ? -v : v;
    return p;
slow : {
    char *end;
    *value = strtod(s, &end);
    return end;
}
}

/* a * 10^k: one exact power where the table has it (|k| <= 22: the common case). */
static double scale10(double a, int k)
{
    if (k >= 0 && k <= 22)
        return a * exact_pow10[k];
    if (k < 0 && k >= -22)
        return a / exact_pow10[-k];
    return a * pow(10.0, k);
}

/* round(a * 10^k) for a * 10^k in [0, 2^52): adding 0.5 is exact there, so truncating is
 * llround's half-away-from-zero, without the library call. */
static uint64_t round_scaled(double a, int k)
{
    return (uint64_t)(scale10(a, k) + 0.5);
}

/* floor(log10(a)) for a positive double, give or take one, from its binary exponent: a
 * lies in [2^(b-1), 2^b), so log10(a) lies in [(b-1) log10 2, b log10 2), shorter than 1;
 * 1233 / 4096 is log10 2 within 5e-6 (within 1e-3 over a float's exponents), which may move
 * the floor by one more. The caller steps from below to the exact one. */
static int decimal_exponent(double a)
{
    uint64_t bits;
    memcpy(&bits, &a, sizeof bits);
    int b = (int)(bits >> 52 & 0x7ff) - 1022, x = (b - 1) * 1233;
    return x >= 0 ? x / 4096 : -((-x + 4095) / 4096);
}

size_t sdfd_format_float(float f, char *out)
{
    char *o = out;
    if (!isfinite(f)) { /* JSON has no Inf or NaN; an uploaded first-order volume's steep
                         * plane extended far out can pass float32. The loops below would
                         * never end. */
        memcpy(o, "null", 4);
        return 4;
    }
    if (f == 0) {
        memcpy(o, signbit(f) ? "-0.0" : "0", signbit(f) ? 4 : 1);
        return signbit(f) ? 4 : 1;
    }
    double a = fabs((double)f);
    if (f < 0)
        *o++ = '-';
    /* m = a * 10^(8 - e) rounded: nine digits, 10^8 <= m < 10^9. Start at or below
     * floor(log10(a)), where m >= 10^8, and step up while m has ten digits (rounding can carry
     * it there): the first e that fits is the one %g's nine digits use. */
    int e = decimal_exponent(a) - 1;
    uint64_t m = round_scaled(a, 8 - e);
    while (m >= 1000000000u)
        m = round_scaled(a, 8 - ++e);
    char d[9];
    for (int i = 8; i >= 0; i--, m /= 10)
        d[i] = (char)('0' + m % 10);
    int n = 9;
    while (n > 1 && d[n - 1] == '0') /* as %g: no trailing zeros */
        n--;
    if (e >= -4 && e < 9) { /* plain notation, as %g chooses for these exponents */
        if (e < 0) {
            *o++ = '0';
            *o++ = '.';
            for (int i = -1; i > e; i--)
                *o++ = '0';
            memcpy(o, d, (size_t)n);
            o += n;
        } else {
            for (int i = 0; i <= e; i++)
                *o++ = i < n ? d[i] : '0';
            if (n > e + 1) {
                *o++ = '.';
                memcpy(o, d + e + 1, (size_t)(n - e - 1));
                o += n - e - 1;
            }
        }
    } else {
        *o++ = d[0];
        if (n > 1) {
            *o++ = '.';
            memcpy(o, d + 1, (size_t)(n - 1));
            o += n - 1;
        }
        *o++ = 'e';
        *o++ = e < 0 ? '-' : '+';
        int x = e < 0 ? -e : e;
        if (x >= 10) /* float exponents have at most two digits */
            *o++ = (char)('0' + x / 10);
        *o++ = (char)('0' + x % 10);
    }
    return (size_t)(o - out);
}
