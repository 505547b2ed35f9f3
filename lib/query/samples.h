/* samples.h - the parameters and sample sets of the convolution-filtered field
 * (sdf_query_filtered in sdf.h; the paper is docs/papers/convolution-filtering-sdf.md,
 * sec. 4-5).
 *
 * A sample set is drawn once per request from its seed: displacements s_i with weights w_i
 * summing to 1 (1/n for samples drawn from the kernel's density, eq. 10; w(s_i) normalised
 * for the regular 3^3 grid, eq. 9). Kept apart from the evaluation (filter.h) so bakes can
 * resolve options and tests can look at the samples themselves. */
#ifndef SDF_QUERY_SAMPLES_H
#define SDF_QUERY_SAMPLES_H

#include <math.h>

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

/* Gaussian w_a has standard deviation sigma = 1 / sqrt(2a) per axis (eq. 9's kernel). */
static inline double sdf__gaussian_sigma(double a) { return 1 / sqrt(2 * a); }

#endif
