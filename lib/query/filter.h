/* filter.h - the sample sets of the convolution-filtered field (sdf_query_filtered in
 * sdf.h; the paper is docs/papers/convolution-filtering-sdf.md, sec. 4-5).
 *
 * A sample set is drawn once per request from its seed: displacements s_i with weights w_i
 * summing to 1 (1/n for samples drawn from the kernel's density, eq. 10; w(s_i) normalised
 * for the regular 3^3 grid, eq. 9). Kept apart from the evaluation so tests can look at the
 * samples themselves. */
#ifndef SDF_QUERY_FILTER_H
#define SDF_QUERY_FILTER_H

#include "sdf/sdf.h"

typedef struct sdf__samples {
    int n;
    double (*offset)[3]; /* s_i, in mesh units (already scaled by the kernel's width) */
    double *weight;      /* w_i, summing to 1 */
} sdf__samples;

/* Draw the sample set of fully resolved options (no zero defaults left). Returns 0 or
 * SDF_ENOMEM. */
int sdf__samples_draw(const sdf_filter_options *f, sdf__samples *out);
void sdf__samples_free(sdf__samples *s);

/* Resolve the zero defaults of `in` for `mesh` and validate every parameter. Returns 0, or
 * SDF_EINVAL with a message saying which value is wrong and what is allowed. */
int sdf__filter_resolve(const sdf_mesh *mesh, const sdf_filter_options *in,
                        sdf_filter_options *out, sdf_diag *diag);

/* An upper bound of the bytes sdf_query_filtered allocates for `count` points with fully
 * resolved options `f` (gradient: whether it is asked for), its inner queries' included. */
size_t sdf__filter_scratch_bound(const sdf_filter_options *f, size_t count, int gradient,
                                 int threads);

#endif
