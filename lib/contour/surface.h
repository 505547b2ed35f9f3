/* surface.h - the inside of an sdf_surface (sdf.h), which both ways of extracting it fill:
 * marching cubes (extract.c) and dual contouring (dual.c). */
#ifndef SDF_CONTOUR_SURFACE_H
#define SDF_CONTOUR_SURFACE_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

struct sdf_surface {
    float *vertices;     /* 3 per vertex, malloc'd */
    uint32_t *triangles; /* 3 per triangle, malloc'd */
    size_t vertex_count, triangle_count;
};

#endif
