/* raycast.c - majority-of-parities inside test (see raycast.h). */
#include "sign/raycast.h"

#include <math.h>
#include <string.h>

/* Directions far from the axes and from each other, so axis-aligned meshes (CAD, boxes)
 * are never grazed systematically. */
static const float base_dirs[5][3] = {
    {0.4264f, 0.7416f, 0.5179f},  {-0.8138f, 0.3115f, 0.4907f}, {0.2308f, -0.6142f, 0.7546f},
    {-0.3327f, -0.5489f, -0.7668f}, {0.6991f, 0.1423f, -0.7007f},
};

static uint32_t hash_point(const float p[3], uint32_t salt)
{
    uint32_t h = 2166136261u ^ salt;
    uint32_t bits[3];
    memcpy(bits, p, sizeof bits);
    for (int i = 0; i < 3; i++) {
        h ^= bits[i];
        h *= 16777619u;
        h ^= h >> 15;
    }
    h *= 0x2c1b3c6dU;
    return h ^ (h >> 12);
}

static int parity(const sdf__bvh *bvh, const float p[3], int ray)
{
    float dir[3];
    for (int i = 0; i < 3; i++) {
        float jitter = (float)(hash_point(p, (uint32_t)(3 * ray + i)) & 0xffff) / 65535.0f - 0.5f;
        dir[i] = base_dirs[ray][i] + 0.1f * jitter;
    }
    return (int)(sdf__bvh_crossings(bvh, p, dir) & 1u);
}

int sdf__raycast_inside(const sdf__bvh *bvh, const float p[3])
{
    int votes = parity(bvh, p, 0) + parity(bvh, p, 1) + parity(bvh, p, 2);
    if (votes == 0 || votes == 3)
        return votes == 3;
    votes += parity(bvh, p, 3) + parity(bvh, p, 4);
    return votes >= 3;
}
