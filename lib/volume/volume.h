/* volume.h - the inside of an sdf_volume, shared by the modules that bake, evaluate, pack
 * and store volumes (the public description is sdf_volume_info in sdf.h). */
#ifndef SDF_VOLUME_VOLUME_H
#define SDF_VOLUME_VOLUME_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

struct sdf_volume {
    sdf_volume_info info;
    size_t nodes;     /* N M K */
    int channels;     /* 32-bit words per node */
    union {
        float *f;     /* FLOAT32 */
        uint32_t *u;  /* PACKED32 */
        void *p;
    } data;
};

/* Check a description (dims, spacing, order and encoding, ranges). 0 or SDF_EINVAL /
 * SDF_ELIMIT with a message. */
int sdf__volume_check_info(const sdf_volume_info *info, sdf_diag *diag);

/* A volume with checked `info` and uninitialised node data. 0 or SDF_ENOMEM. */
int sdf__volume_alloc(const sdf_volume_info *info, sdf_volume **out);

/* The plane a x + b y + c z + d of first-order node (i, j, k), decoded (either encoding). */
void sdf__volume_node_plane(const sdf_volume *v, size_t i, size_t j, size_t k, double plane[4]);

/* Position of node (i, j, k). */
static inline void sdf__volume_node(const sdf_volume_info *info, size_t i, size_t j, size_t k,
                                    double out[3])
{
    out[0] = info->origin[0] + (double)i * info->spacing[0];
    out[1] = info->origin[1] + (double)j * info->spacing[1];
    out[2] = info->origin[2] + (double)k * info->spacing[2];
}

#endif
