/* signs.h - one bit per node of the grid marching cubes walks: set where the node is inside
 * (its value minus iso is < 0). The grid is the volume's nodes and, with caps, one layer of
 * outside nodes around them.
 *
 * The values are read once, to make the bits; after that, which edges cross is the xor of
 * two rows of bits, how many cross is a popcount, and which cells hold surface is a few word
 * operations, so the values are read again only at the crossings and in the cells the
 * surface passes through: the rest of the grid costs a bit per node.
 *
 * Rows run along x: row (j, k) holds n[0] bits in `words` 64-bit words, bit i of the row
 * being node i (bit i % 64 of word i / 64); bits past n[0] are 0. */
#ifndef SDF_CONTOUR_SIGNS_H
#define SDF_CONTOUR_SIGNS_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

/* Set bits of x. A SWAR sum, because the baseline x86-64 target has no POPCNT instruction and
 * __builtin_popcountll becomes a library call there (its cost showed in profiles of the
 * extraction, which takes one per crossing it numbers). */
static inline unsigned sdf__popcount64(uint64_t x)
{
    x -= (x >> 1) & 0x5555555555555555ull;
    x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
    x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0full;
    return (unsigned)((x * 0x0101010101010101ull) >> 56);
}

typedef struct sdf__signs {
    const sdf_volume *v;
    double iso;
    int pad;          /* 1: a layer of outside nodes around the volume's */
    size_t n[3];      /* nodes per axis, the padding included */
    size_t words;     /* per row */
    uint64_t *bits;   /* row (j, k) at bits + (k n[1] + j) words */
} sdf__signs;

/* The value at node (i, j, k) of the grid, minus iso, as a float (+1e30 beyond the volume):
 * the one number every test of a node's side and every crossing is computed from. */
float sdf__signs_value(const sdf__signs *s, size_t i, size_t j, size_t k);

/* A node's gradient: a first-order node's plane's (a, b, c), a zero-order node's by central
 * differences of the values: 1; 0 for a node beyond the volume (caps), which has none. */
int sdf__signs_gradient(const sdf__signs *s, size_t i, size_t j, size_t k, double g[3]);

/* Grid coordinates (node units, the padding counted) to world coordinates. */
void sdf__signs_world(const sdf__signs *s, const double at[3], float out[3]);

/* Make the bits of s (v, iso, pad set; n and words filled here) on `threads` threads.
 * 0 or SDF_ENOMEM. */
int sdf__signs_fill(sdf__signs *s, int threads);
void sdf__signs_free(sdf__signs *s);

/* The crossing edges of one row of the family `axis` into out[words]: bit i set when the
 * edge from node (i, j, k) to its neighbour along axis (x: i + 1, y: j + 1, z: k + 1) joins
 * nodes of different sides. The row must have that neighbour. */
void sdf__signs_cross(const sdf__signs *s, int axis, size_t j, size_t k, uint64_t *out);

/* The cells of row (j, k) (cell i: nodes i..i+1, j..j+1, k..k+1) whose corners are not all
 * on one side, into out[words]. j + 1 < n[1], k + 1 < n[2]. */
void sdf__signs_active(const sdf__signs *s, size_t j, size_t k, uint64_t *out);

#endif
