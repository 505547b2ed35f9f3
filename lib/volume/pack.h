/* pack.h - the 32-bit packing of a first-order node (the TDF paper, sec. 5.3): the unit
 * normal (a, b, c) in octahedral coordinates (Meyer et al. 2010), 10 bits each as snorm, and
 * the plane's value at its node in 12 bits snorm over [-range, range].
 *
 * The paper packs the constant term d; we pack the plane's value at the node instead, from
 * which d = value - (a, b, c) . node is recovered exactly: d grows with the node's distance
 * from the world origin while the value is bounded by the distances in the volume, so the
 * same 12 bits resolve it much more finely (and independently of where the volume lies). */
#ifndef SDF_VOLUME_PACK_H
#define SDF_VOLUME_PACK_H

#include <stdint.h>

#define SDF__PACK_NORMAL_BITS 10
#define SDF__PACK_VALUE_BITS 12

/* Pack unit normal n and `value` (|value| <= range is kept; beyond, it clamps). Of the four
 * quantised octahedral neighbours the one closest to n is kept. */
uint32_t sdf__pack_plane(const double n[3], double value, double range);

/* Unpack: a unit normal and the value. */
void sdf__unpack_plane(uint32_t word, double range, double n[3], double *value);

#endif
