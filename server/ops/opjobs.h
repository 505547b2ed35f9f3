/* opjobs.h - the operations that start and follow jobs (docs/api.md, "Volumes" and "Jobs"):
 * a bake of a mesh, field operations on a volume, the list of jobs, one job, its
 * cancellation. The jobs themselves run in volumes.c; these check the request, look the
 * inputs up through the cache and answer 202 with the job. With --catalog a job is a row
 * any replica may claim (catjobs.h, jobrunner.h), and the routes read the rows. Handlers of
 * call.h. */
#ifndef SDFD_OPJOBS_H
#define SDFD_OPJOBS_H

#include "ops/call.h"

int sdfd_op_bake(sdfd_call *call);       /* POST /v1/meshes/{name}/bake */
int sdfd_op_volume_ops(sdfd_call *call); /* POST /v1/volumes/{name}/ops */
int sdfd_op_job_list(sdfd_call *call);   /* GET /v1/jobs */
int sdfd_op_job_get(sdfd_call *call);    /* GET /v1/jobs/{id} */
int sdfd_op_job_cancel(sdfd_call *call); /* DELETE /v1/jobs/{id} */

/* The job runner's start (sdfd_jobrunner_start_fn; user: the sdfd_server): a claimed job's
 * request read again and its job started here under its id. */
int sdfd_op_start_shared(void *user, const sdfd_catjob *job, char *err, size_t cap);

#endif
