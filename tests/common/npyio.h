/* npyio.h - the .npy files the command-line tools read and write: (N, 3) query points in,
 * (N,) or (N, 4) float32 results out. Both exit the process with a message on failure:
 * they are for tools, not the library. */
#ifndef SDF_TESTS_NPYIO_H
#define SDF_TESTS_NPYIO_H

#include <stddef.h>

/* Load an (N, 3) float32/float64 .npy into a new float array; *n receives N. */
float *npy_load_points(const char *tool, const char *path, size_t *n);

/* Write `dist` (and, for cols 4, `vec3` as 3 more columns) as float32 (N,) or (N, 4). */
void npy_write_results(const char *tool, const char *path, size_t n, int cols, const float *dist,
                       const float *vec3);

#endif
