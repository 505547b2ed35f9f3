/* catimport.c - a file store copied into the catalog (catimport.h). */
#include "state/catimport.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "core/log.h"
#include "state/catblob.h"
#include "state/store.h"

/* Does the catalog hold `name` with exactly n bytes of this hash? */
static int unchanged(sdfd_catalog *c, sdfd_item_kind kind, const char *name, size_t n,
                     const unsigned char hash[SDFD_CATALOG_HASH_BYTES])
{
    sdfd_catalog_item item;
    char err[256];
    if (sdfd_catalog_read(c, kind, name, &item, NULL, err, sizeof err))
        return 0;
    free(item.info);
    return item.bytes == n && !memcmp(hash, item.hash, SDFD_CATALOG_HASH_BYTES);
}

/* One item: 0 (counted), or an error that stops the import. */
static int import_one(sdfd_store *s, sdfd_catalog *c, sdfd_item_kind kind, const char *name,
                      sdfd_catimport_counts *counts, char *err, size_t cap)
{
    sdfd_sidecar meta;
    sdfd_stamp stamp;
    void *data = NULL;
    char why[400];
    int rc = sdfd_store_read(s, kind, name, &meta, &data, &stamp, why, sizeof why);
    if (rc == SDF_EFORMAT || rc == SDF_ENOTFOUND) {
        sdfd_log("warn", "import", "%s %s left out: %s", sdfd_catalog_kind_name(kind), name, why);
        counts->damaged++;
        free(meta.info);
        return 0;
    }
    if (rc) {
        snprintf(err, cap, "%s", why);
        return rc;
    }
    unsigned char hash[SDFD_CATALOG_HASH_BYTES];
    if (sdfd_catblob_hash(data, meta.bytes, hash)) {
        snprintf(err, cap, "cannot compute SHA-256 (GnuTLS)");
        rc = SDF_EIO;
    } else if (unchanged(c, kind, name, meta.bytes, hash)) {
        counts->unchanged++;
    } else {
        uint64_t version;
        rc = sdfd_catalog_put_hashed(c, kind, name, data, meta.bytes, hash, meta.format,
                                     meta.info, &version, NULL, err, cap);
        if (!rc) {
            counts->copied++;
            sdfd_log("info", "import", "%s %s: %zu bytes, version %llu",
                     sdfd_catalog_kind_name(kind), name, meta.bytes,
                     (unsigned long long)version);
        }
    }
    free(data);
    free(meta.info);
    return rc;
}

int sdfd_catimport_run(const char *dir, sdfd_catalog *c, sdfd_catimport_counts *counts,
                       char *err, size_t cap)
{
    *counts = (sdfd_catimport_counts){0};
    sdfd_store *s = NULL;
    if (sdfd_store_open(dir, &s, err, cap))
        return SDF_EINVAL;
    int rc = sdfd_store_probe(s) ? SDFD_EUNAVAILABLE : 0;
    if (rc)
        snprintf(err, cap, "%s cannot be read as an sdfd store", dir);
    for (int kind = SDFD_ITEM_MESH; !rc && kind <= SDFD_ITEM_VOLUME; kind++) {
        char(*names)[SDFD_MAX_NAME + 1] = NULL;
        size_t n = sdfd_store_names(s, kind, &names);
        for (size_t i = 0; !rc && i < n; i++)
            rc = import_one(s, c, kind, names[i], counts, err, cap);
        free(names);
    }
    sdfd_store_close(s);
    return rc;
}
