/* files.h - whole-file reading for the tests and the benchmark. */
#ifndef SDF_TESTS_FILES_H
#define SDF_TESTS_FILES_H

#include <stddef.h>

/* Read all of `path` into a new NUL-terminated buffer; NULL (errno set) on failure. */
char *read_whole_file(const char *path, size_t *size);

#endif
