/* numtext.c - decimal text <-> numbers for the JSON body (see numtext.h). */
#include "numtext.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* 10^0 .. 10^22: every one is exact in a double. */
static const double exact_pow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                       1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                       1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int digit(char c) { return c >= '0' && c <= '9'; }

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
    if (mantissa > (UINT64_C(1) << 53) || exp10 < -22 || exp10 > 22)
        goto slow;
    /* Both operands exact, so the one rounding is IEEE's: the correctly rounded result. */
    double v = (double)mantissa;
    v = exp10 < 0 ? v / exact_pow10[-exp10] : v * exact_pow10[exp10];
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

size_t sdfd_format_float(float f, char *out)
{
    char *o = out;
    if (f == 0) {
        memcpy(o, signbit(f) ? "-0.0" : "0", signbit(f) ? 4 : 1);
        return signbit(f) ? 4 : 1;
    }
    double a = fabs((double)f);
    if (f < 0)
        *o++ = '-';
    /* m = a * 10^(8 - e) rounded: nine digits, 10^8 <= m < 10^9. */
    int e = (int)floor(log10(a));
    uint64_t m = (uint64_t)llround(scale10(a, 8 - e));
    if (m >= 1000000000u) { /* log10 rounded down too little, or rounding carried */
        e++;
        m = (uint64_t)llround(scale10(a, 8 - e));
    } else if (m < 100000000u) {
        e--;
        m = (uint64_t)llround(scale10(a, 8 - e));
    }
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
