/* filter.h - the memory bound of the convolution-filtered field's evaluation (filter.c;
 * sdf_query_filtered in sdf.h), for callers that budget a filtered request or bake before
 * running it. Its options and samples are samples.h's. */
#ifndef SDF_QUERY_FILTER_H
#define SDF_QUERY_FILTER_H

#include "sdf/sdf.h"

/* An upper bound of the bytes sdf_query_filtered allocates for `count` points with fully
 * resolved options `f` (gradient: whether it is asked for), its inner queries' included. */
size_t sdf__filter_scratch_bound(const sdf_filter_options *f, size_t count, int gradient,
                                 int threads);

#endif
