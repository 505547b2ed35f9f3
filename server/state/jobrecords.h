/* jobrecords.h - jobs' records (bakes and field operations) in the store (DIR/jobs/ID.json,
 * store.h), so that a job's state and result outlive the process and a restart knows which
 * jobs it interrupted. The cache (cache.h) calls these from the volumes' job hooks. */
#ifndef SDFD_JOBRECORDS_H
#define SDFD_JOBRECORDS_H

#include "state/store.h"
#include "state/volumes.h"

/* A job was accepted: lock its record (before it says queued, so that only a record whose
 * lock no live process holds is taken for interrupted), then write it. Returns the lock's fd
 * (or -1), the token sdfd_jobrecords_ended takes. */
int sdfd_jobrecords_started(sdfd_store *store, const sdfd_job_status *s);
/* A job ended: its final record, then the lock released. */
void sdfd_jobrecords_ended(sdfd_store *store, const sdfd_job_status *s, int token);
void sdfd_jobrecords_forgotten(sdfd_store *store, const char *id);
/* A job from its record: 0 or SDF_ENOTFOUND. */
int sdfd_jobrecords_read(sdfd_store *store, const char *id, sdfd_job_status *out);
/* Jobs the store says are queued or running, but whose owner is gone (their lock is free):
 * a restart interrupted them. They end failed, in the store and in `volumes`' list. */
void sdfd_jobrecords_restore(sdfd_store *store, sdfd_volumes *volumes);

#endif
