/* pack.c - octahedral normal + snorm value packing of first-order nodes (see pack.h). */
#include "volume/pack.h"

#include <math.h>

#define NORMAL_MAX ((1 << (SDF__PACK_NORMAL_BITS - 1)) - 1) /* 511 */
#define VALUE_MAX ((1 << (SDF__PACK_VALUE_BITS - 1)) - 1)   /* 2047 */

static double sign_not_zero(double x) { return x < 0 ? -1.0 : 1.0; }

/* Unit vector -> the octahedron's square [-1, 1]^2: project onto |x|+|y|+|z| = 1, then fold
 * the lower half over the diagonals. */
static void octahedral_encode(const double n[3], double *u, double *v)
{
    double l1 = fabs(n[0]) + fabs(n[1]) + fabs(n[2]);
    double x = n[0] / l1, y = n[1] / l1;
    if (n[2] < 0) {
        double fx = (1 - fabs(y)) * sign_not_zero(x), fy = (1 - fabs(x)) * sign_not_zero(y);
        x = fx, y = fy;
    }
    *u = x, *v = y;
}

static void octahedral_decode(double u, double v, double n[3])
{
    double z = 1 - fabs(u) - fabs(v);
    if (z < 0) {
        double fu = (1 - fabs(v)) * sign_not_zero(u), fv = (1 - fabs(u)) * sign_not_zero(v);
        u = fu, v = fv;
    }
    double len = sqrt(u * u + v * v + z * z);
    n[0] = u / len, n[1] = v / len, n[2] = z / len;
}

static int clamp_int(long q, int max)
{
    return q > max ? max : q < -max ? -max : (int)q;
}

/* Two's-complement field of `bits` bits <-> int. */
static uint32_t to_field(int q, int bits) { return (uint32_t)q & ((1u << bits) - 1); }

static int from_field(uint32_t word, int shift, int bits)
{
    int q = (int)((word >> shift) & ((1u << bits) - 1));
    return q >= 1 << (bits - 1) ? q - (1 << bits) : q;
}

uint32_t sdf__pack_plane(const double n[3], double value, double range)
{
    double u, v;
    octahedral_encode(n, &u, &v);
    /* Rounding each coordinate alone is not the nearest normal: try floor and ceil of both. */
    int best_u = 0, best_v = 0;
    double best_dot = -2;
    for (int du = 0; du < 2; du++)
        for (int dv = 0; dv < 2; dv++) {
            int qu = clamp_int((long)floor(u * NORMAL_MAX) + du, NORMAL_MAX);
            int qv = clamp_int((long)floor(v * NORMAL_MAX) + dv, NORMAL_MAX);
            double m[3];
            octahedral_decode((double)qu / NORMAL_MAX, (double)qv / NORMAL_MAX, m);
            double dot = m[0] * n[0] + m[1] * n[1] + m[2] * n[2];
            if (dot > best_dot)
                best_dot = dot, best_u = qu, best_v = qv;
        }
    int qd = range > 0 ? clamp_int(lround(value / range * VALUE_MAX), VALUE_MAX) : 0;
    return to_field(best_u, SDF__PACK_NORMAL_BITS) |
           to_field(best_v, SDF__PACK_NORMAL_BITS) << SDF__PACK_NORMAL_BITS |
           to_field(qd, SDF__PACK_VALUE_BITS) << (2 * SDF__PACK_NORMAL_BITS);
}

void sdf__unpack_plane(uint32_t word, double range, double n[3], double *value)
{
    int qu = from_field(word, 0, SDF__PACK_NORMAL_BITS);
    int qv = from_field(word, SDF__PACK_NORMAL_BITS, SDF__PACK_NORMAL_BITS);
    int qd = from_field(word, 2 * SDF__PACK_NORMAL_BITS, SDF__PACK_VALUE_BITS);
    /* -512 and -2048 are never written; read them as the most negative written value. */
    if (qu < -NORMAL_MAX) qu = -NORMAL_MAX;
    if (qv < -NORMAL_MAX) qv = -NORMAL_MAX;
    if (qd < -VALUE_MAX) qd = -VALUE_MAX;
    octahedral_decode((double)qu / NORMAL_MAX, (double)qv / NORMAL_MAX, n);
    *value = (double)qd / VALUE_MAX * range;
}
