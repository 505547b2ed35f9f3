/* numtext.h - decimal text <-> numbers for the JSON body, fast on the common cases.
 *
 * A JSON query of 1,000,000 points carries 3,000,000 numbers in and 1,000,000 or more out;
 * with strtod and printf("%.9g") they cost more than the query itself (perf: ~45 % of the
 * server's time on fandisk). Both directions here are exact where it matters:
 *  - parsing gives the same double as strtod: numbers of at most 19 significant digits and a
 *    decimal exponent within +-22 whose digits fit 2^53 take Clinger's fast path (one exact
 *    multiplication or division by an exact power of ten, correctly rounded); longer digits
 *    (to 19, as the 17 of Python's json) with an exponent within +-19 are scaled exactly in
 *    128-bit integers and rounded once; everything else goes to strtod;
 *  - printing writes 9 significant digits (as %.9g does), computed in double: the last digit
 *    may differ from printf's by one, but any such text is within 1.5e-8 relative of the
 *    float, less than half its spacing (>= 2.98e-8), so it reads back as the same float
 *    (directly, or through a double as JSON parsers do). Tested exhaustively on random floats
 *    in tests/server/test_numtext.c. */
#ifndef SDFD_NUMTEXT_H
#define SDFD_NUMTEXT_H

#include <stddef.h>

/* Longest text sdfd_format_float writes, without a terminator. */
#define SDFD_FLOAT_TEXT_MAX 16

/* Parse the number at s (the caller has checked the JSON grammar's first character: '-' or
 * a digit). `s` must be followed by a non-numeric byte or a NUL before the buffer ends, as
 * for strtod. Returns the end of the number, or s if there is none. */
const char *sdfd_parse_number(const char *s, double *value);

/* Write f as JSON text (no terminator); returns its length. -0 is written "-0.0" so it does
 * not read back as the integer 0; Inf and NaN, which JSON lacks, are written null. */
size_t sdfd_format_float(float f, char *out);

#endif
