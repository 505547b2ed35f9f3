/* slicerender.c - values to an RGB picture (see slicerender.h). The colour map follows
 * K. Moreland, "Diverging Color Maps for Scientific Visualization" (2009): sRGB -> CIELAB
 * (D65) -> Msh, interpolated there through an unsaturated white midpoint. */
#include "ops/slicerender.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sdf/sdf.h"

/* ---- the scale ---------------------------------------------------------------------------- */

/* 1, 2 or 5 times a power of ten, the nearest to x. */
static double nice_step(double x)
{
    double p = pow(10, floor(log10(x))), m = x / p;
    return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p;
}

void sdfd_slice_scale_of(const float *values, size_t n, int diverging, double step,
                         sdfd_slice_scale *out)
{
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; i++)
        if (isfinite(values[i]))
            lo = fmin(lo, values[i]), hi = fmax(hi, values[i]);
    if (!(lo <= hi))
        lo = hi = 0;
    double r = diverging ? fmax(fabs(lo), fabs(hi)) : fmax(hi, 0);
    if (!(r > 0))
        r = 1;
    *out = (sdfd_slice_scale){.diverging = diverging, .lo = diverging ? -r : 0, .hi = r,
                              .min = lo, .max = hi, .step = step > 0 ? step : nice_step(r / 5)};
}

/* ---- the colour map ----------------------------------------------------------------------- */

typedef struct msh {
    double m, s, h;
} msh;

static const double white_xyz[3] = {0.95047, 1.0, 1.08883};

static double lab_f(double t)
{
    return t > 216.0 / 24389 ? cbrt(t) : t * 841.0 / 108 + 4.0 / 29;
}

static double lab_finv(double t)
{
    return t > 6.0 / 29 ? t * t * t : (t - 4.0 / 29) * 108.0 / 841;
}

static msh msh_of_srgb(const double rgb[3])
{
    double lin[3], xyz[3], f[3];
    for (int c = 0; c < 3; c++)
        lin[c] = rgb[c] <= 0.04045 ? rgb[c] / 12.92 : pow((rgb[c] + 0.055) / 1.055, 2.4);
    xyz[0] = 0.4124564 * lin[0] + 0.3575761 * lin[1] + 0.1804375 * lin[2];
    xyz[1] = 0.2126729 * lin[0] + 0.7151522 * lin[1] + 0.0721750 * lin[2];
    xyz[2] = 0.0193339 * lin[0] + 0.1191920 * lin[1] + 0.9503041 * lin[2];
    for (int c = 0; c < 3; c++)
        f[c] = lab_f(xyz[c] / white_xyz[c]);
    double l = 116 * f[1] - 16, a = 500 * (f[0] - f[1]), b = 200 * (f[1] - f[2]);
    double m = sqrt(l * l + a * a + b * b);
    return (msh){m, m > 0 ? acos(l / m) : 0, atan2(b, a)};
}

static void srgb_of_msh(msh c, unsigned char out[3])
{
    double l = c.m * cos(c.s), a = c.m * sin(c.s) * cos(c.h), b = c.m * sin(c.s) * sin(c.h);
    double fy = (l + 16) / 116, f[3] = {fy + a / 500, fy, fy - b / 200}, xyz[3];
    for (int k = 0; k < 3; k++)
        xyz[k] = lab_finv(f[k]) * white_xyz[k];
    double lin[3] = {3.2404542 * xyz[0] - 1.5371385 * xyz[1] - 0.4985314 * xyz[2],
                     -0.9692660 * xyz[0] + 1.8760108 * xyz[1] + 0.0415560 * xyz[2],
                     0.0556434 * xyz[0] - 0.2040259 * xyz[1] + 1.0572252 * xyz[2]};
    for (int k = 0; k < 3; k++) {
        double v = fmin(fmax(lin[k], 0), 1);
        v = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
        out[k] = (unsigned char)lround(255 * v);
    }
}

/* Moreland's hue spin: an unsaturated end takes a hue near the saturated one's. */
static double adjust_hue(msh sat, double m_unsat)
{
    if (sat.m >= m_unsat)
        return sat.h;
    double spin = sat.s * sqrt(m_unsat * m_unsat - sat.m * sat.m) / (sat.m * sin(sat.s));
    return sat.h > -M_PI / 3 ? sat.h + spin : sat.h - spin;
}

void sdfd_slice_colour(double t, unsigned char rgb[3])
{
    static const double cool[3] = {59 / 255.0, 76 / 255.0, 192 / 255.0},
                        warm[3] = {180 / 255.0, 4 / 255.0, 38 / 255.0};
    msh a = msh_of_srgb(cool), b = msh_of_srgb(warm);
    double x = (fmin(fmax(t, -1), 1) + 1) / 2; /* 0 cool .. 1 warm */
    double mid = fmax(fmax(a.m, b.m), 88);
    /* the two ends are far apart in hue: through white, each half from its end */
    if (x < 0.5)
        b = (msh){mid, 0, 0}, x = 2 * x;
    else
        a = (msh){mid, 0, 0}, x = 2 * x - 1;
    if (a.s < 0.05 && b.s > 0.05)
        a.h = adjust_hue(b, a.m);
    else if (b.s < 0.05 && a.s > 0.05)
        b.h = adjust_hue(a, b.m);
    srgb_of_msh((msh){(1 - x) * a.m + x * b.m, (1 - x) * a.s + x * b.s, (1 - x) * a.h + x * b.h},
                rgb);
}

/* ---- lines -------------------------------------------------------------------------------- */

#define LUT 512

typedef struct canvas {
    const float *v;
    size_t w, h;
    unsigned char *rgb;
    unsigned char *mark; /* per pixel: 1 iso line, 2 zero line */
} canvas;

/* A pair of neighbouring pixels a, b: if a level lies between them, mark the one nearer it. */
static void mark_pair(canvas *c, const sdfd_slice_scale *s, size_t a, size_t b)
{
    double va = c->v[a], vb = c->v[b];
    if (!isfinite(va) || !isfinite(vb))
        return;
    if (s->diverging && (va < 0) != (vb < 0)) {
        c->mark[fabs(va) <= fabs(vb) ? a : b] = 2;
        return;
    }
    double ba = floor(va / s->step), bb = floor(vb / s->step);
    if (ba == bb)
        return;
    double level = s->step * fmax(ba, bb);
    size_t near = fabs(va - level) <= fabs(vb - level) ? a : b;
    if (c->mark[near] == 0)
        c->mark[near] = 1;
}

static void paint(canvas *c, const sdfd_slice_scale *s)
{
    unsigned char lut[LUT + 1][3];
    double from = s->diverging ? -1 : 0;
    for (int i = 0; i <= LUT; i++)
        sdfd_slice_colour(from + (1 - from) * i / LUT, lut[i]);
    for (size_t j = 0; j < c->h; j++)
        for (size_t i = 0; i < c->w; i++) {
            size_t k = j * c->w + i;
            if (i + 1 < c->w)
                mark_pair(c, s, k, k + 1);
            if (j + 1 < c->h)
                mark_pair(c, s, k, k + c->w);
        }
    for (size_t k = 0; k < c->w * c->h; k++) {
        unsigned char *px = c->rgb + 3 * k;
        double v = c->v[k];
        if (!isfinite(v)) {
            memset(px, 128, 3);
            continue;
        }
        double x = (v - s->lo) / (s->hi - s->lo);
        memcpy(px, lut[(int)lround(fmin(fmax(x, 0), 1) * LUT)], 3);
        if (c->mark[k] == 2)
            memset(px, 0, 3);
        else if (c->mark[k] == 1) /* iso line: 40 % toward a dark grey, the colour shows */
            for (int ch = 0; ch < 3; ch++)
                px[ch] = (unsigned char)((px[ch] * 3 + 40 * 2) / 5);
    }
}

/* ---- the legend --------------------------------------------------------------------------- */

static const char glyph_chars[] = "0123456789-.+e";
static const unsigned char glyphs[][7] = { /* 5 bits a row, the top row first */
    {14, 17, 19, 21, 25, 17, 14}, {4, 12, 4, 4, 4, 4, 14},   {14, 17, 1, 2, 4, 8, 31},
    {31, 2, 4, 2, 1, 17, 14},     {2, 6, 10, 18, 31, 2, 2},  {31, 16, 30, 1, 1, 17, 14},
    {6, 8, 16, 30, 17, 17, 14},   {31, 1, 2, 4, 8, 8, 8},    {14, 17, 17, 14, 17, 17, 14},
    {14, 17, 17, 15, 1, 2, 12},   {0, 0, 0, 31, 0, 0, 0},    {0, 0, 0, 0, 0, 12, 12},
    {0, 4, 4, 31, 4, 4, 0},       {0, 0, 14, 17, 31, 16, 14}};

static void put(unsigned char *rgb, size_t w, size_t x, size_t y, unsigned char grey)
{
    memset(rgb + 3 * (y * w + x), grey, 3);
}

/* Text at (x, y), its top-left; returns the x after it. */
static size_t text(unsigned char *rgb, size_t w, size_t x, size_t y, const char *s)
{
    for (; *s; s++, x += 6) {
        const char *at = strchr(glyph_chars, *s);
        if (!at || x + 5 > w)
            continue;
        const unsigned char *g = glyphs[at - glyph_chars];
        for (int r = 0; r < 7; r++)
            for (int b = 0; b < 5; b++)
                if (g[r] >> (4 - b) & 1)
                    put(rgb, w, x + (size_t)b, y + (size_t)r, 0);
    }
    return x;
}

static void legend(unsigned char *rgb, size_t w, size_t top, const sdfd_slice_scale *s)
{
    memset(rgb + 3 * top * w, 245, 3 * w * SDFD_LEGEND_HEIGHT);
    char lo[32], hi[32];
    snprintf(lo, sizeof lo, "%.3g", s->lo);
    snprintf(hi, sizeof hi, "%.3g", s->hi);
    size_t x0 = 3 + 6 * strlen(lo) + 4, right = 6 * strlen(hi) + 4 + 3;
    if (x0 + 8 + right > w) /* too narrow for both numbers and a bar */
        return;
    size_t x1 = w - right;
    text(rgb, w, 3, top + 6, lo);
    text(rgb, w, x1 + 4, top + 6, hi);
    for (size_t x = x0; x < x1; x++) {
        unsigned char c[3];
        double t = (double)(x - x0) / (double)(x1 - 1 - x0);
        sdfd_slice_colour(s->diverging ? 2 * t - 1 : t, c);
        for (size_t y = top + 4; y < top + 14; y++)
            memcpy(rgb + 3 * (y * w + x), c, 3);
    }
    /* a tick at each iso level (when they are far enough apart to tell) and the zero */
    double levels = (s->hi - s->lo) / s->step;
    for (double k = ceil(s->lo / s->step); levels <= (double)(x1 - x0) / 3 && k * s->step <= s->hi;
         k++) {
        size_t x = x0 + (size_t)lround((k * s->step - s->lo) / (s->hi - s->lo) * (x1 - 1 - x0));
        int zero = k == 0 && s->diverging;
        for (size_t y = top + (zero ? 1 : 2); y < top + (zero ? 17 : 6); y++)
            put(rgb, w, x, y, zero ? 0 : 90);
    }
}

int sdfd_slice_render(const float *values, size_t width, size_t height,
                      const sdfd_slice_scale *scale, unsigned char **rgb, size_t *image_height)
{
    size_t extra = width >= SDFD_LEGEND_MIN_WIDTH ? SDFD_LEGEND_HEIGHT : 0;
    canvas c = {values, width, height, malloc(3 * width * (height + extra)),
                calloc(width * height, 1)};
    if (!c.rgb || !c.mark) {
        free(c.rgb), free(c.mark);
        return SDF_ENOMEM;
    }
    paint(&c, scale);
    free(c.mark);
    if (extra)
        legend(c.rgb, width, height, scale);
    *rgb = c.rgb;
    *image_height = height + extra;
    return 0;
}
