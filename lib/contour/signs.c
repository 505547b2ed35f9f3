/* signs.c - the nodes' sides as bits (signs.h). */
#include "contour/signs.h"

#include <stdlib.h>

#include "core/parallel.h"
#include "volume/volume.h"

#define OUTSIDE 1e30f

static double volume_value(const sdf_volume *v, size_t i, size_t j, size_t k)
{
    size_t idx = (k * v->info.dims[1] + j) * v->info.dims[0] + i;
    if (v->info.order == 0)
        return v->data.f[idx];
    double plane[4], at[3];
    sdf__volume_node_plane(v, i, j, k, plane);
    sdf__volume_node(&v->info, i, j, k, at);
    return plane[0] * at[0] + plane[1] * at[1] + plane[2] * at[2] + plane[3];
}

float sdf__signs_value(const sdf__signs *s, size_t i, size_t j, size_t k)
{
    if (s->pad) {
        if (i == 0 || j == 0 || k == 0 || i == s->n[0] - 1 || j == s->n[1] - 1 ||
            k == s->n[2] - 1)
            return OUTSIDE;
        i--, j--, k--;
    }
    return (float)(volume_value(s->v, i, j, k) - s->iso);
}

/* A zero-order node's gradient: central differences of the node values (one-sided on the
 * volume's faces). */
static void difference_gradient(const sdf_volume *v, size_t i, size_t j, size_t k, double g[3])
{
    const size_t *n = v->info.dims, at[3] = {i, j, k}, step[3] = {1, n[0], n[0] * n[1]};
    size_t idx = (k * n[1] + j) * n[0] + i;
    for (int a = 0; a < 3; a++) {
        size_t lo = at[a] ? idx - step[a] : idx, hi = at[a] + 1 < n[a] ? idx + step[a] : idx;
        double span = (double)((hi - lo) / step[a]) * v->info.spacing[a];
        g[a] = ((double)v->data.f[hi] - (double)v->data.f[lo]) / span;
    }
}

int sdf__signs_gradient(const sdf__signs *s, size_t i, size_t j, size_t k, double g[3])
{
    if (s->pad) {
        if (i == 0 || j == 0 || k == 0 || i == s->n[0] - 1 || j == s->n[1] - 1 ||
            k == s->n[2] - 1)
            return 0;
        i--, j--, k--;
    }
    if (s->v->info.order == 0) {
        difference_gradient(s->v, i, j, k, g);
        return 1;
    }
    double plane[4];
    sdf__volume_node_plane(s->v, i, j, k, plane);
    g[0] = plane[0], g[1] = plane[1], g[2] = plane[2];
    return 1;
}

void sdf__signs_world(const sdf__signs *s, const double at[3], float out[3])
{
    const sdf_volume_info *in = &s->v->info;
    for (int a = 0; a < 3; a++)
        out[a] = (float)(in->origin[a] + (at[a] - s->pad) * in->spacing[a]);
}

/* Order 0 without caps: a row straight from the volume's floats. */
static void fill_row_direct(const sdf__signs *s, size_t j, size_t k, uint64_t *row)
{
    size_t n0 = s->n[0];
    const float *f = s->v->data.f + (k * s->n[1] + j) * n0;
    for (size_t w = 0; w < s->words; w++) {
        uint64_t bits = 0;
        size_t end = (w + 1) * 64 < n0 ? (w + 1) * 64 : n0;
        for (size_t i = w * 64; i < end; i++) /* sdf__signs_value's expression */
            bits |= (uint64_t)((float)(f[i] - s->iso) < 0) << (i - w * 64);
        row[w] = bits;
    }
}

static void fill_row(const sdf__signs *s, size_t j, size_t k, uint64_t *row)
{
    if (!s->pad && s->v->info.order == 0) {
        fill_row_direct(s, j, k, row);
        return;
    }
    for (size_t w = 0; w < s->words; w++)
        row[w] = 0;
    for (size_t i = 0; i < s->n[0]; i++)
        row[i / 64] |= (uint64_t)(sdf__signs_value(s, i, j, k) < 0) << (i % 64);
}

static void fill_rows(void *ctx, size_t begin, size_t end, int worker)
{
    sdf__signs *s = ctx;
    (void)worker;
    for (size_t r = begin; r < end; r++)
        fill_row(s, r % s->n[1], r / s->n[1], s->bits + r * s->words);
}

int sdf__signs_fill(sdf__signs *s, int threads)
{
    const sdf_volume_info *in = &s->v->info;
    for (int a = 0; a < 3; a++)
        s->n[a] = in->dims[a] + 2 * (size_t)s->pad;
    s->words = (s->n[0] + 63) / 64;
    size_t rows = s->n[1] * s->n[2];
    s->bits = malloc(rows * s->words * sizeof *s->bits + 1);
    if (!s->bits)
        return SDF_ENOMEM;
    size_t chunk = 16384 / s->n[0] + 1;
    sdf__parallel_for(rows, chunk, sdf__effective_threads(threads, rows, chunk), fill_rows, s);
    return 0;
}

void sdf__signs_free(sdf__signs *s)
{
    free(s->bits);
    s->bits = NULL;
}

static const uint64_t *row_of(const sdf__signs *s, size_t j, size_t k)
{
    return s->bits + (k * s->n[1] + j) * s->words;
}

/* Bit i of the result is bit i + 1 of r (a row shifted down by one node). */
static uint64_t next_bits(const uint64_t *r, size_t w, size_t words)
{
    return r[w] >> 1 | (w + 1 < words ? r[w + 1] << 63 : 0);
}

/* Keep bits 0..count-1 of a row. */
static void clip(uint64_t *out, size_t words, size_t count)
{
    for (size_t w = 0; w < words; w++) {
        size_t lo = w * 64;
        if (lo >= count)
            out[w] = 0;
        else if (count - lo < 64)
            out[w] &= ((uint64_t)1 << (count - lo)) - 1;
    }
}

void sdf__signs_cross(const sdf__signs *s, int axis, size_t j, size_t k, uint64_t *out)
{
    const uint64_t *a = row_of(s, j, k);
    const uint64_t *b = axis == 1 ? row_of(s, j + 1, k) : axis == 2 ? row_of(s, j, k + 1) : a;
    for (size_t w = 0; w < s->words; w++)
        out[w] = a[w] ^ (axis == 0 ? next_bits(a, w, s->words) : b[w]);
    clip(out, s->words, axis == 0 ? s->n[0] - 1 : s->n[0]);
}

void sdf__signs_active(const sdf__signs *s, size_t j, size_t k, uint64_t *out)
{
    const uint64_t *r[4] = {row_of(s, j, k), row_of(s, j + 1, k), row_of(s, j, k + 1),
                            row_of(s, j + 1, k + 1)};
    for (size_t w = 0; w < s->words; w++) {
        uint64_t any = 0, all = ~(uint64_t)0;
        for (int m = 0; m < 4; m++) {
            uint64_t pair_any = r[m][w] | next_bits(r[m], w, s->words);
            uint64_t pair_all = r[m][w] & next_bits(r[m], w, s->words);
            any |= pair_any, all &= pair_all;
        }
        out[w] = any & ~all;
    }
    clip(out, s->words, s->n[0] - 1);
}
