/* pageassets.h - the page's files as byte arrays, generated at build time by
 * server/page/embed.py from server/page/ and the sdfd-client package's browser modules
 * (clients/js/src), which page.c serves. */
#ifndef SDFD_PAGEASSETS_H
#define SDFD_PAGEASSETS_H

#include <stddef.h>

typedef struct sdfd_page_asset {
    const char *name;          /* served as /static/<name>; index.html also as / */
    const char *type;          /* Content-Type */
    const unsigned char *data;
    size_t size;
} sdfd_page_asset;

extern const sdfd_page_asset sdfd_page_assets[];
extern const size_t sdfd_page_asset_count;

#endif
