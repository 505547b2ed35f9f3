/* pngenc.c - PNG encoding through libpng (see pngenc.h; not png.h, which would hide
 * libpng's own header). libpng reports errors by longjmp out of its
 * calls; the output grows in a buffer of our own through its write callback. The compression
 * level is zlib's fastest: a slice is encoded per request, and its smooth colours and long
 * runs compress well enough at level 1 for a picture a browser shows at once. */
#include "ops/pngenc.h"

#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sdf/sdf.h"

typedef struct sink {
    char *data;
    size_t len, cap;
    int failed;
    char *err;
    size_t err_cap;
} sink;

static void on_write(png_structp png, png_bytep bytes, png_size_t n)
{
    sink *s = png_get_io_ptr(png);
    if (s->failed)
        return;
    if (s->len + n > s->cap) {
        size_t cap = s->cap ? s->cap : 1 << 16;
        while (cap < s->len + n)
            cap *= 2;
        char *grown = realloc(s->data, cap);
        if (!grown) {
            s->failed = 1;
            return;
        }
        s->data = grown, s->cap = cap;
    }
    memcpy(s->data + s->len, bytes, n);
    s->len += n;
}

static void on_flush(png_structp png)
{
    (void)png;
}

static void on_error(png_structp png, png_const_charp message)
{
    sink *s = png_get_error_ptr(png);
    snprintf(s->err, s->err_cap, "libpng: %s", message);
    png_longjmp(png, 1);
}

static void on_warning(png_structp png, png_const_charp message)
{
    (void)png, (void)message;
}

int sdfd_png_encode(const unsigned char *rgb, size_t width, size_t height, char **out,
                    size_t *len, char *err, size_t cap)
{
    sink s = {.err = err, .err_cap = cap};
    err[0] = '\0';
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &s, on_error, on_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        snprintf(err, cap, "out of memory for the PNG encoder");
        return SDF_ENOMEM;
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        free(s.data);
        return SDF_EIO;
    }
    png_set_write_fn(png, &s, on_write, on_flush);
    png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 8, PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, 1);
    png_write_info(png, info);
    for (size_t y = 0; y < height; y++)
        png_write_row(png, rgb + 3 * width * y);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    if (s.failed) {
        free(s.data);
        snprintf(err, cap, "out of memory for a %zu x %zu PNG", width, height);
        return SDF_ENOMEM;
    }
    *out = s.data;
    *len = s.len;
    return 0;
}
