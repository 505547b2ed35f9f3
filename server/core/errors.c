/* errors.c - names, messages and HTTP statuses of every code sdfd answers with (errors.h):
 * the library's from its table, the server's from SDFD_ERRNO_MAP. */
#include "core/errors.h"

enum {
#define SDFD__STATUS_ENUM(name, http) SDFD_STATUS_##name = (http),
    SDFD_LIBRARY_STATUS_MAP(SDFD__STATUS_ENUM)
#undef SDFD__STATUS_ENUM
};

const char *sdfd_strerror(int err)
{
    switch (err) {
#define SDFD__ERRNO_MSG(name, value, http, msg) case SDFD_##name: return msg;
        SDFD_ERRNO_MAP(SDFD__ERRNO_MSG)
#undef SDFD__ERRNO_MSG
    default: return sdf_strerror(err);
    }
}

/* Both tables in one switch: a server value that a library code also uses is a duplicate
 * case, which does not compile. */
const char *sdfd_errname(int err)
{
    switch (err) {
    case SDF_OK: return "OK";
#define SDFD__LIB_NAME(name, value, msg) case SDF_##name: return #name;
        SDF_ERRNO_MAP(SDFD__LIB_NAME)
#undef SDFD__LIB_NAME
#define SDFD__ERRNO_NAME(name, value, http, msg) case SDFD_##name: return #name;
        SDFD_ERRNO_MAP(SDFD__ERRNO_NAME)
#undef SDFD__ERRNO_NAME
    default: return "EUNKNOWN";
    }
}

int sdfd_http_status(int err)
{
    switch (err) {
    case SDF_OK: return 200;
#define SDFD__LIB_HTTP(name, value, msg) case SDF_##name: return SDFD_STATUS_##name;
        SDF_ERRNO_MAP(SDFD__LIB_HTTP)
#undef SDFD__LIB_HTTP
#define SDFD__ERRNO_HTTP(name, value, http, msg) case SDFD_##name: return http;
        SDFD_ERRNO_MAP(SDFD__ERRNO_HTTP)
#undef SDFD__ERRNO_HTTP
    default: return 500;
    }
}
