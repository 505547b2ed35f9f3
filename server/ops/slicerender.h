/* slicerender.h - a slice's values as a picture: colours, iso-distance lines, the zero line
 * and a legend, into an 8-bit RGB image (pngenc.h encodes it).
 *
 * Colours: a signed field is shown in a perceptually uniform diverging map (Moreland's
 * "cool to warm", interpolated in his Msh form of CIELAB): blue inside (negative), red
 * outside, his neutral near-white (L* = 88) at zero, over a range symmetric about zero so that equal distances inside
 * and outside get equal strength. A non-negative field (unsigned distance, gradient
 * magnitude, error) uses the warm half from that near-white at 0. Iso lines every `step`, the zero set
 * (sign changes between neighbouring pixels) as a black line one pixel wide, drawn on the
 * pixel of each changing pair nearer the level, so the line lies within half a pixel of it.
 * Non-finite values are grey. The legend is a strip below the slice: the range's end values
 * (a built-in 5x7 bitmap font) around a colour bar with a tick at every iso level. */
#ifndef SDFD_SLICERENDER_H
#define SDFD_SLICERENDER_H

#include <stddef.h>

#define SDFD_LEGEND_HEIGHT 18 /* rows under the slice, when it is SDFD_LEGEND_MIN_WIDTH wide */
#define SDFD_LEGEND_MIN_WIDTH 96

typedef struct sdfd_slice_scale {
    int diverging;  /* signed field: symmetric range, a zero line */
    double lo, hi;  /* the colour map's ends: -r..r, or 0..r */
    double min, max; /* the finite values' range (0, 0 when none is finite) */
    double step;    /* iso-line spacing */
} sdfd_slice_scale;

/* The scale of `n` values: the range, and `step` when it is > 0, else a 1-2-5 step giving
 * about five lines across the larger side of the range. */
void sdfd_slice_scale_of(const float *values, size_t n, int diverging, double step,
                         sdfd_slice_scale *out);

/* The colour of map position t in -1..1 (diverging) as 8-bit sRGB. */
void sdfd_slice_colour(double t, unsigned char rgb[3]);

/* Render width x height values (rows from the top) into a new malloc'd RGB image of
 * width x *image_height pixels (the slice, then the legend when it fits). 0 or SDF_ENOMEM. */
int sdfd_slice_render(const float *values, size_t width, size_t height,
                      const sdfd_slice_scale *scale, unsigned char **rgb, size_t *image_height);

#endif
