/* page.h - sdfd's page: GET / and its files under GET /static/{name}, served from the copies
 * embedded at build time (pageassets.h). */
#ifndef SDFD_PAGE_H
#define SDFD_PAGE_H

#include "transport/httpreq.h"

/* req->name is the file under /static/, or "" for / (index.html); 404 for any other. */
enum MHD_Result sdfd_http_page(sdfd_http_request *req);

#endif
