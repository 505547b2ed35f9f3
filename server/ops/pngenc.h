/* pngenc.h - an 8-bit RGB image as a PNG file in memory, by libpng (Debian's libpng-dev): the
 * slice images' encoding. */
#ifndef SDFD_PNGENC_H
#define SDFD_PNGENC_H

#include <stddef.h>

/* Encode width x height pixels (rows from the top, 3 bytes a pixel) into a new malloc'd
 * buffer (*out, *len). 0, SDF_ENOMEM, or SDF_EIO when libpng refuses, with its message in
 * `err`. */
int sdfd_png_encode(const unsigned char *rgb, size_t width, size_t height, char **out,
                    size_t *len, char *err, size_t cap);

#endif
