/* backfile.h - the file store (store.h) as the cache's backing (backing.h): what --data-dir
 * alone gives. A version is the sidecar's stamp; changes by another process are found by
 * comparing stamps, so it never calls a backing's `changed` callback. */
#ifndef SDFD_BACKFILE_H
#define SDFD_BACKFILE_H

#include "state/backing.h"

/* The backing of `store`, which it owns from now on (closed by ops->close). */
void sdfd_backfile_init(sdfd_store *store, sdfd_backing *out);

#endif
