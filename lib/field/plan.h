/* plan.h - a chain of field operations as the re-distancings and value shifts it takes,
 * with the redundant ones merged and each re-distancing's band derived backwards from what
 * the steps after it need. */
#ifndef SDF_FIELD_PLAN_H
#define SDF_FIELD_PLAN_H

#include <stddef.h>

#include "sdf/sdf.h"

typedef struct sdf__field_step {
    int redistance; /* 1: re-distance phi; 0: phi += shift */
    double shift;
    double want;    /* redistance: the band its op asked for (REDISTANCE r), 0 if none,
                       INFINITY for the whole grid */
    double band;    /* redistance: the distance up to which it must be exact (INFINITY: the
                       whole grid); shift: the band the steps after it need */
    size_t op;      /* the index of the op it comes from */
} sdf__field_step;

#define SDF__FIELD_MAX_STEPS (6 * SDF_FIELD_MAX_OPS)

/* Expand ops[count] (checked by the caller) into steps (SDF__FIELD_MAX_STEPS of room); the
 * result must be exact up to `band` from its surface, and a re-distancing needs its input
 * exact up to `margin` (the interface's neighbours). Returns the number of steps. */
size_t sdf__field_plan(const sdf_field_op *ops, size_t count, double band, double margin,
                       sdf__field_step *steps);

#endif
