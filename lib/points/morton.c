/* morton.c - the Morton visit order of a batch (see morton.h).
 *
 * Keys are code << 32 | index, sorted by three passes over the code's 10-bit digits. The
 * keys are cut into parts of a power-of-two length, one per thread. Each pass scatters every
 * part by its own write cursors (the running sums over buckets, then parts), which is the
 * serial stable sort's order, and counts as it writes the next pass's digits per destination
 * part, so no pass reads the keys twice. */
#include "points/morton.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/bigmem.h"
#include "core/parallel.h"
#include "core/workspace.h"
#include "sdf/sdf.h"

#define DIGIT_BITS 10
#define BUCKETS (1u << DIGIT_BITS)
#define PASSES 3
/* Below this many points one thread sorts: starting threads (several times per sort) costs
 * more than the second core saves. */
#define PARALLEL_MIN_POINTS ((size_t)1 << 17)
/* At most this many parts: the sort is bound by memory well before, and each pair of parts
 * keeps a histogram. */
#define MAX_PARTS 8

typedef struct morton_sort {
    const char *points;
    size_t stride, count;
    size_t parts;
    unsigned part_shift;     /* part p holds positions [p << part_shift, (p + 1) << part_shift) */
    float (*part_lo)[3], (*part_hi)[3];
    float lo[3], scale[3];
    uint64_t *src, *dst;
    uint32_t *order;         /* the last pass writes indices here */
    int pass;
    uint32_t *cursor;        /* [part][bucket]: this pass's counts, then write positions */
    uint32_t *next;          /* [writer part][destination part][bucket]: the next pass's */
} morton_sort;

/* Spread the low 10 bits of v so they occupy every third bit. */
static uint32_t spread10(uint32_t v)
{
    v &= 0x3ff;
    v = (v | v << 16) & 0x030000ff;
    v = (v | v << 8) & 0x0300f00f;
    v = (v | v << 4) & 0x030c30c3;
    v = (v | v << 2) & 0x09249249;
    return v;
}

uint32_t sdf__morton_code(const float p[3], const float lo[3], const float scale[3])
{
    uint32_t c[3];
    for (int k = 0; k < 3; k++)
        c[k] = (uint32_t)((p[k] - lo[k]) * scale[k]);
    return spread10(c[0]) | spread10(c[1]) << 1 | spread10(c[2]) << 2;
}

static unsigned digit(uint64_t key, int pass)
{
    return (unsigned)(key >> (32 + DIGIT_BITS * pass)) & (BUCKETS - 1);
}

static void part_span(const morton_sort *s, size_t part, size_t *begin, size_t *end)
{
    *begin = part << s->part_shift;
    size_t e = (part + 1) << s->part_shift;
    *end = e < s->count ? e : s->count;
}

static const float *point(const morton_sort *s, size_t i)
{
    return (const float *)(s->points + i * s->stride);
}

static void bounds_range(void *ctx, size_t first_part, size_t end_part, int worker)
{
    (void)worker;
    morton_sort *s = ctx;
    for (size_t part = first_part; part < end_part; part++) {
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        size_t begin, end;
        part_span(s, part, &begin, &end);
        for (size_t i = begin; i < end; i++) {
            const float *p = point(s, i);
            for (int k = 0; k < 3; k++) {
                lo[k] = p[k] < lo[k] ? p[k] : lo[k];
                hi[k] = p[k] > hi[k] ? p[k] : hi[k];
            }
        }
        memcpy(s->part_lo[part], lo, sizeof lo);
        memcpy(s->part_hi[part], hi, sizeof hi);
    }
}

/* Each part's keys and the counts of their first digits. */
static void keys_range(void *ctx, size_t first_part, size_t end_part, int worker)
{
    (void)worker;
    const morton_sort *s = ctx;
    uint64_t *keys = s->src;
    float lo[3], scale[3];
    memcpy(lo, s->lo, sizeof lo);
    memcpy(scale, s->scale, sizeof scale);
    for (size_t part = first_part; part < end_part; part++) {
        uint32_t *count = s->cursor + part * BUCKETS;
        size_t begin, end;
        part_span(s, part, &begin, &end);
        for (size_t i = begin; i < end; i++) {
            uint64_t key = (uint64_t)sdf__morton_code(point(s, i), lo, scale) << 32 | i;
            keys[i] = key;
            count[digit(key, 0)]++;
        }
    }
}

/* One pass over a part: each key to its cursor's position, counting the next pass's digit
 * for the part the position falls in. */
static void scatter_range(void *ctx, size_t first_part, size_t end_part, int worker)
{
    (void)worker;
    const morton_sort *s = ctx;
    /* Locals: the stores below could alias the context's fields. */
    const uint64_t *src = s->src;
    uint64_t *dst = s->dst;
    uint32_t *order = s->order;
    int pass = s->pass;
    unsigned shift = s->part_shift;
    for (size_t part = first_part; part < end_part; part++) {
        uint32_t *cursor = s->cursor + part * BUCKETS;
        uint32_t *next = s->next + part * s->parts * BUCKETS;
        size_t begin, end;
        part_span(s, part, &begin, &end);
        if (pass == PASSES - 1) {
            for (size_t i = begin; i < end; i++)
                order[cursor[digit(src[i], pass)]++] = (uint32_t)src[i];
            continue;
        }
        memset(next, 0, s->parts * BUCKETS * sizeof *next);
        for (size_t i = begin; i < end; i++) {
            uint64_t key = src[i];
            size_t at = cursor[digit(key, pass)]++;
            dst[at] = key;
            next[(at >> shift) * BUCKETS + digit(key, pass + 1)]++;
        }
    }
}

/* Counts per (part, bucket) into write positions: a bucket's keys follow every smaller
 * bucket's, and within a bucket, the parts' keys follow in part order (stable). */
static void cursors_from_counts(morton_sort *s)
{
    uint32_t sum = 0;
    for (size_t b = 0; b < BUCKETS; b++)
        for (size_t part = 0; part < s->parts; part++) {
            uint32_t *c = &s->cursor[part * BUCKETS + b], n = *c;
            *c = sum;
            sum += n;
        }
}

/* The next pass's counts per destination part, summed over the parts that wrote them. */
static void counts_from_next(morton_sort *s)
{
    memset(s->cursor, 0, s->parts * BUCKETS * sizeof *s->cursor);
    for (size_t writer = 0; writer < s->parts; writer++)
        for (size_t part = 0; part < s->parts; part++) {
            const uint32_t *n = s->next + (writer * s->parts + part) * BUCKETS;
            uint32_t *c = s->cursor + part * BUCKETS;
            for (size_t b = 0; b < BUCKETS; b++)
                c[b] += n[b];
        }
}

/* How the keys are cut: parts of 2^shift positions, one per thread, at most MAX_PARTS. */
static size_t parts_for(size_t count, int threads, unsigned *shift)
{
    int workers = count < PARALLEL_MIN_POINTS ? 1 : sdf__effective_threads(threads, count, 1);
    size_t want = workers < MAX_PARTS ? (size_t)workers : MAX_PARTS;
    *shift = 0;
    while (((size_t)1 << *shift) * want < count)
        ++*shift;
    return count ? ((count - 1) >> *shift) + 1 : 0; /* at most `want` */
}

size_t sdf__morton_scratch_bound(size_t count, int threads)
{
    unsigned shift;
    size_t parts = parts_for(count, threads, &shift);
    return sdf__big_size(2 * count * sizeof(uint64_t)) +
           (parts + parts * parts) * BUCKETS * sizeof(uint32_t) + 2 * parts * 3 * sizeof(float);
}

int sdf__morton_order(const char *points, size_t stride, size_t count, int threads,
                      sdf_workspace *ws, uint32_t *order)
{
    if (count > UINT32_MAX)
        return SDF_ENOMEM;
    if (count == 0)
        return 0;
    morton_sort s = {.points = points, .stride = stride, .count = count, .order = order};
    s.parts = parts_for(count, threads, &s.part_shift);
    uint64_t *keys = sdf__ws_alloc(ws, SDF__WS_MORTON_KEYS, 2 * count * sizeof *keys);
    s.src = keys;
    s.cursor = calloc(s.parts * BUCKETS, sizeof *s.cursor);
    s.next = malloc(s.parts * s.parts * BUCKETS * sizeof *s.next);
    s.part_lo = malloc(s.parts * sizeof *s.part_lo);
    s.part_hi = malloc(s.parts * sizeof *s.part_hi);
    int rc = s.src && s.cursor && s.next && s.part_lo && s.part_hi ? 0 : SDF_ENOMEM;
    if (!rc) {
        int run = (int)s.parts;
        s.dst = s.src + count;
        sdf__parallel_for(s.parts, 1, run, bounds_range, &s);
        for (int k = 0; k < 3; k++) {
            s.lo[k] = INFINITY;
            float hi = -INFINITY;
            for (size_t part = 0; part < s.parts; part++) {
                s.lo[k] = s.part_lo[part][k] < s.lo[k] ? s.part_lo[part][k] : s.lo[k];
                hi = s.part_hi[part][k] > hi ? s.part_hi[part][k] : hi;
            }
            s.scale[k] = hi > s.lo[k] ? 1023.0f / (hi - s.lo[k]) : 0.0f;
        }
        sdf__parallel_for(s.parts, 1, run, keys_range, &s);
        for (s.pass = 0; s.pass < PASSES; s.pass++) {
            if (s.pass)
                counts_from_next(&s);
            cursors_from_counts(&s);
            sdf__parallel_for(s.parts, 1, run, scatter_range, &s);
            uint64_t *t = s.src;
            s.src = s.dst;
            s.dst = t;
        }
    }
    sdf__ws_free(ws, keys);
    free(s.cursor), free(s.next), free(s.part_lo), free(s.part_hi);
    return rc;
}
