/* exr.h - volumes as OpenEXR files through the OpenEXRCore C API (layout in sdf.h and
 * docs/volumes.md). */
#ifndef SDF_VOLUME_EXR_H
#define SDF_VOLUME_EXR_H

#include <stddef.h>

#include "sdf/sdf.h"

/* Encode into a new malloc'ed buffer. */
int sdf__exr_save(const sdf_volume *volume, void **data, size_t *size, sdf_diag *diag);

/* Decode `size` bytes. */
int sdf__exr_load(const void *data, size_t size, sdf_volume **out, sdf_diag *diag);

#endif
