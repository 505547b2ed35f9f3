/* points.h - sdfq's files: query points in (.npy float32/float64 (N, 3) little-endian, or
 * CSV x,y,z per line with an optional header line) and results out (.npy as the server's
 * HTTP npy answers lay them out, or CSV). Every length in an input is checked against the
 * bytes present before anything is allocated from it; a refusal is one line on stderr
 * naming the file (and the line, for CSV). */
#ifndef SDFQ_POINTS_H
#define SDFQ_POINTS_H

#include <stddef.h>
#include <stdint.h>

typedef struct sdfq_points {
    float *xyz;   /* 3 * count floats */
    size_t count;
} sdfq_points;

/* Read `path` ("-": standard input) by its extension (.npy, .csv), else by its first bytes.
 * 0, or SDFQ_INPUT after a message. */
int sdfq_read_points(const char *path, sdfq_points *out);
/* The same from memory; `what` names the input in messages. */
int sdfq_parse_npy(const unsigned char *data, size_t size, const char *what, sdfq_points *out);
int sdfq_parse_csv(const char *data, size_t size, const char *what, sdfq_points *out);
void sdfq_points_free(sdfq_points *p);

typedef enum sdfq_out_format { SDFQ_OUT_CSV, SDFQ_OUT_NPY } sdfq_out_format;

/* Results: `count` points of `words` 32-bit words each (the RESULT layout); `columns` is
 * the CSV header, comma-separated, one name per word ("triangle" marks the closest mode's
 * uint32 word, which npy writes as the server's structured array does). Written to `path`
 * ("-": standard output). 0, or SDFQ_OUTPUT after a message. */
int sdfq_write_results(const char *path, sdfq_out_format format, const char *columns,
                       unsigned words, const uint32_t *data, size_t count);
/* The format `path` asks for: .npy -> npy, else CSV. */
sdfq_out_format sdfq_out_format_of(const char *path);

#endif
