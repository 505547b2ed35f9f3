/* catimport.h - `sdfd --catalog URI --import DIR`: the meshes and volumes of a file store
 * (store.h) copied into the catalog, as the way from --data-dir to --catalog. Each item is
 * one put of its bytes as stored, with its description; an item the catalog already holds
 * with the same bytes is left as it is, so an import cut short is finished by running it
 * again. An item whose files fail their checks is logged and left out (the store is not
 * changed, beyond its layout brought to the current one). Job records stay behind: they
 * describe the file store's replicas' own jobs. */
#ifndef SDFD_CATIMPORT_H
#define SDFD_CATIMPORT_H

#include <stddef.h>

#include "state/catalog.h"

typedef struct sdfd_catimport_counts {
    size_t copied, unchanged, damaged;
} sdfd_catimport_counts;

/* Import the store at dir into c: 0 (every item copied, unchanged or damaged: counted), or
 * the first error that stopped it (the store cannot be opened, PostgreSQL went away), with
 * err set. */
int sdfd_catimport_run(const char *dir, sdfd_catalog *c, sdfd_catimport_counts *counts,
                       char *err, size_t cap);

#endif
