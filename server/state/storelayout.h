/* storelayout.h - the store's layout on disk (docs/api.md, "Data directory") and the step
 * that brings an older store to it at open. Layout 2 keeps each kind's data files in
 * KIND/data/, a directory of their own, so that no item name, whatever it spells, can reach
 * them (a sidecar is always KIND/NAME.json); layout 1 kept them beside the sidecars. */
#ifndef SDFD_STORELAYOUT_H
#define SDFD_STORELAYOUT_H

#include <stddef.h>

/* The layout this sdfd writes, recorded in DIR/SDFD_STORE_MARKER as {"store":"sdfd",
 * "layout":N}. */
#define SDFD_STORE_LAYOUT 2
#define SDFD_STORE_MARKER "sdfd-store.json"
/* Each kind's directory and its data files' (indexed by sdfd_item_kind). */
#define SDFD_STORE_KIND_DIRS {"meshes", "volumes"}
#define SDFD_STORE_DATA_DIRS {"meshes/data", "volumes/data"}

/* Bring the store at dir (its directories made, its lock held) to SDFD_STORE_LAYOUT: refuse a
 * newer layout than this sdfd's, move layout 1's data files into KIND/data/ (each rename is
 * atomic, so a crash midway is finished by the next open), and record the layout in the
 * marker. 0, or -1 with err set. */
int sdfd_storelayout_settle(const char *dir, char *err, size_t cap);

#endif
