/* raycast.h - inside/outside by ray parity: a point inside a closed mesh crosses it an odd
 * number of times along any ray. A ray grazing an edge or vertex can miscount, so we cast
 * three rays in generic directions jittered per point (a hash of its coordinates, so the
 * answer does not depend on threads or order), and two more when they disagree; the
 * majority wins. */
#ifndef SDF_SIGN_RAYCAST_H
#define SDF_SIGN_RAYCAST_H

#include "bvh/embree.h"

/* 1 when p is inside by majority of ray parities, else 0. Thread-safe. */
int sdf__raycast_inside(const sdf__bvh *bvh, const float p[3]);

#endif
