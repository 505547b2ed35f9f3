/* shapes.h - the analytic fields of the field-operation tests and benchmark: each input
 * field (rarely a distance) and the exact signed distance of what an operation must make of
 * it, derived in shapes.c. Negative inside, lengths in the unit cube [-1, 1]^3. */
#ifndef SDF_TESTS_FIELD_SHAPES_H
#define SDF_TESTS_FIELD_SHAPES_H

#include "sdf/sdf.h"

typedef double (*shape_fn)(const double p[3]);
/* The exact result at p, or NAN where the case does not know it (not measured there). */
typedef double (*truth_fn)(const double p[3]);

typedef struct field_case {
    const char *name;
    shape_fn input;
    truth_fn truth;
    sdf_field_op ops[2];
    size_t count;
    double band;       /* measured where |truth| <= band (and truth is known) */
} field_case;

/* The cases of docs/volumes.md's accuracy table, in its order. */
extern const field_case field_cases[];
extern const size_t field_case_count;

/* A zero-order volume sampling `f` on n^3 nodes over [-1, 1]^3 (NULL on failure). */
sdf_volume *shape_volume(shape_fn f, size_t n);

/* Error of `v` against c->truth over the nodes where it is known and within c->band, as a
 * fraction of the spacing: mean and max; returns the number of nodes measured. */
size_t shape_error(const sdf_volume *v, const field_case *c, double *mean, double *max);

#endif
