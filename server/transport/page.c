/* page.c - the page's routes (see page.h). The files live in the binary for its whole life,
 * so MHD sends them from there without a copy; browsers are asked to revalidate, so a
 * rebuilt sdfd's page is never mixed with a cached older script. */
#include "transport/page.h"

#include <string.h>

#include "core/errors.h"
#include "transport/pageassets.h"

enum MHD_Result sdfd_http_page(sdfd_http_request *req)
{
    const char *name = req->name[0] ? req->name : "index.html";
    for (size_t i = 0; i < sdfd_page_asset_count; i++) {
        const sdfd_page_asset *a = &sdfd_page_assets[i];
        if (strcmp(a->name, name))
            continue;
        struct MHD_Response *r = MHD_create_response_from_buffer(a->size, (void *)a->data,
                                                                 MHD_RESPMEM_PERSISTENT);
        if (!r)
            return MHD_NO;
        sdfd_http_header h = {"Cache-Control", "no-cache"};
        return sdfd_http_queue(req, 200, a->type, r, a->size, &h, 1);
    }
    return sdfd_http_error(req, SDF_ENOTFOUND, "no file /static/%s", name);
}
