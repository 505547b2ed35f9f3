/* plan.c - the operations as steps (see plan.h), in sdfd's sign convention (negative
 * inside; phi + c erodes the solid by c for c > 0):
 *   REDISTANCE r: R(r)                  OFFSET r: R, phi - r
 *   ROUND r:  R, phi + r, R, phi - r    (erode, re-distance, dilate: an opening)
 *   FILLET r: R, phi - r, R, phi + r    (dilate, re-distance, erode: a closing)
 *   SMOOTH r: ROUND r then FILLET r.
 * The rounding paper's steps 1-4 of rounding say "negative direction" for phi - r, which
 * in its convention (positive inside) erodes; here the operation is named by what it does.
 *
 * Merges: two shifts in a row are one; two re-distancings in a row are one; and a
 * re-distancing between two shifts of the same sign is dropped, merging them: the shift
 * before it left phi a signed distance on the side the second shift moves the surface
 * into, since Minkowski sums compose ((X + B_r) + B_s = X + B_(r+s), likewise erosions).
 * That is the paper's merge of smoothing's two consecutive offsets into one of 2r, which
 * leaves three re-distancings. A REDISTANCE op's own re-distancing is never dropped. */
#include "field/plan.h"

#include <math.h>

static size_t push(sdf__field_step *s, size_t n, int redistance, double shift, double want,
                   size_t op)
{
    s[n] = (sdf__field_step){.redistance = redistance, .shift = shift, .want = want, .op = op};
    return n + 1;
}

static size_t expand(const sdf_field_op *ops, size_t count, sdf__field_step *s)
{
    size_t n = 0;
    for (size_t o = 0; o < count; o++) {
        double r = ops[o].r;
        switch (ops[o].kind) {
        case SDF_FIELD_REDISTANCE:
            n = push(s, n, 1, 0, r > 0 ? r : INFINITY, o);
            break;
        case SDF_FIELD_OFFSET:
            n = push(s, n, 1, 0, 0, o);
            n = push(s, n, 0, -r, 0, o);
            break;
        case SDF_FIELD_ROUND:
        case SDF_FIELD_FILLET:
        case SDF_FIELD_SMOOTH: {
            double first = ops[o].kind == SDF_FIELD_FILLET ? -r : r;
            n = push(s, n, 1, 0, 0, o);
            n = push(s, n, 0, first, 0, o);
            n = push(s, n, 1, 0, 0, o);
            n = push(s, n, 0, -first, 0, o);
            if (ops[o].kind == SDF_FIELD_SMOOTH) { /* then the fillet */
                n = push(s, n, 1, 0, 0, o);
                n = push(s, n, 0, -r, 0, o);
                n = push(s, n, 1, 0, 0, o);
                n = push(s, n, 0, r, 0, o);
            }
            break;
        }
        }
    }
    return n;
}

static size_t drop(sdf__field_step *s, size_t n, size_t at)
{
    for (size_t i = at; i + 1 < n; i++)
        s[i] = s[i + 1];
    return n - 1;
}

/* One merge, if any applies; returns the new count (n when none did). */
static size_t merge_once(sdf__field_step *s, size_t n)
{
    for (size_t i = 0; i + 1 < n; i++) {
        if (!s[i].redistance && !s[i + 1].redistance) {
            s[i].shift += s[i + 1].shift;
            return drop(s, n, i + 1);
        }
        if (s[i].redistance && s[i + 1].redistance) {
            s[i].want = fmax(s[i].want, s[i + 1].want);
            return drop(s, n, i + 1);
        }
        if (i + 2 < n && !s[i].redistance && s[i + 1].redistance && s[i + 1].want == 0 &&
            !s[i + 2].redistance && s[i].shift * s[i + 2].shift > 0) {
            s[i].shift += s[i + 2].shift;
            n = drop(s, n, i + 2);
            return drop(s, n, i + 1);
        }
    }
    return n;
}

size_t sdf__field_plan(const sdf_field_op *ops, size_t count, double band, double margin,
                       sdf__field_step *steps)
{
    size_t n = expand(ops, count, steps), before;
    do {
        before = n;
        n = merge_once(steps, n);
    } while (n != before);
    double need = band; /* what the steps after the current one need of phi */
    for (size_t i = n; i-- > 0;) {
        if (steps[i].redistance) {
            steps[i].band = fmax(steps[i].want, need);
            need = margin;
        } else {
            steps[i].band = need;
            need += fabs(steps[i].shift);
        }
    }
    return n;
}
