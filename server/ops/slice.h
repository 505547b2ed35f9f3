/* slice.h - a slice image's parameters and its plane (docs/api.md, "Slices").
 *
 * GET .../slice.png takes its parameters as URL arguments. They are parsed here from a plain
 * list of (name, value) pairs, so that every rule (unknown or repeated arguments, by the
 * route's table in urlargs.c, ranges, which arguments go with which mode) is checked without
 * MHD, and each refusal names the argument it is about. The plane is then laid out as a
 * lattice of pixel centres over the bounds: square pixels, `size` of them along the longer
 * side. */
#ifndef SDFD_SLICE_H
#define SDFD_SLICE_H

#include <stddef.h>

#include "ops/filterparams.h"
#include "ops/urlargs.h"
#include "sdf/sdf.h"

#define SDFD_SLICE_DEFAULT_SIZE 512
#define SDFD_SLICE_MAX_SIZE 2048

typedef enum sdfd_slice_mode {
    SDFD_SLICE_SIGNED,   /* signed distance (a volume's value) */
    SDFD_SLICE_DISTANCE, /* unsigned distance */
    SDFD_SLICE_FILTERED, /* the convolution-filtered distance (meshes) */
    SDFD_SLICE_GRADIENT, /* the gradient's magnitude */
    SDFD_SLICE_ERROR     /* |volume - exact signed distance| (volumes baked from a loaded mesh) */
} sdfd_slice_mode;

typedef struct sdfd_slice_params {
    int volume;                  /* a volume's slice, else a mesh's */
    sdfd_slice_mode mode;
    int axis;                    /* 0, 1, 2; -1 with a normal */
    int has_at;
    double at;                   /* coordinate along the axis (default: the bounds' middle) */
    int has_origin;
    double normal[3], origin[3]; /* normal unit length; origin default: the bounds' centre */
    int has_bounds;
    double lo[3], hi[3];         /* default: the mesh's box with a margin, the volume's box */
    int size;                    /* pixels along the longer side */
    double step;                 /* iso-line spacing; 0: chosen from the range */
    sdf_sign_method sign;
    sdf_volume_filter interpolation;
    int npy;                     /* ?format=npy: the values, not a picture */
    sdf_filter_options filter;   /* mode filtered */
    char smoothing_mesh[SDFD_VOLUME_NAME_MAX + 1];
} sdfd_slice_params;

/* Parse the URL arguments of a mesh's or a volume's slice. 0, or SDF_EINVAL with a message
 * in `err` and the argument's name in *argument. */
int sdfd_slice_parse(const sdfd_url_args *args, int volume, sdfd_slice_params *out, char *err,
                     size_t cap, const char **argument);

/* The image's lattice: pixel (i, j) (j counts rows down from the top) is centred at
 * first + i * right + j * down. */
typedef struct sdfd_slice_plane {
    size_t width, height;
    double first[3], right[3], down[3];
} sdfd_slice_plane;

/* Lay the plane out over the parameters' bounds, or else over box_lo..box_hi (the mesh's or
 * volume's box), grown by `margin` times its largest side on every side. */
void sdfd_slice_layout(const sdfd_slice_params *p, const double box_lo[3],
                       const double box_hi[3], double margin, sdfd_slice_plane *out);

/* The pixel centres, row by row from the top, x y z floats (3 * width * height). */
void sdfd_slice_points(const sdfd_slice_plane *plane, float *points);

#endif
