/* test_errors.c - sdfd's error table (server/core/errors.h), which clients see as the `code` and
 * status of every HTTP error body and binary ERROR frame:
 *  - every code of both tables, the library's and the server's, has the name, HTTP status
 *    and message pinned below (docs/api.md and proto/PROTOCOL.md promise the names and
 *    statuses), and the pinned list names every code of both tables;
 *  - no server value is also a library value, and no name is used twice;
 *  - SDF_OK is 200 "OK", anything else 500 "EUNKNOWN" "unknown error". */
#include <string.h>

#include "../common/check.h"
#include "core/errors.h"

static const struct {
    int code;
    const char *name;
    int status;
    const char *message;
} expected[] = {
    {SDF_EINVAL, "EINVAL", 422, "invalid argument"},
    {SDF_ENOMEM, "ENOMEM", 503, "out of memory"},
    {SDF_EIO, "EIO", 500, "cannot read file"},
    {SDF_EFORMAT, "EFORMAT", 415, "unknown or unsupported file format"},
    {SDF_EPARSE, "EPARSE", 422, "malformed data"},
    {SDF_ETRUNC, "ETRUNC", 422, "truncated data"},
    {SDF_ELIMIT, "ELIMIT", 413, "size limit exceeded"},
    {SDF_EEMPTY, "EEMPTY", 422, "mesh has no triangles"},
    {SDF_ENONFINITE, "ENONFINITE", 422, "coordinate is NaN, Inf or beyond +-1e18"},
    {SDF_EINDEX, "EINDEX", 422, "index out of range"},
    {SDF_EBVH, "EBVH", 500, "BVH library (Embree) error"},
    {SDF_ENOTFOUND, "ENOTFOUND", 404, "not found"},
    {SDF_ECANCELED, "ECANCELED", 409, "canceled"},
    {SDFD_EPROTO, "EPROTO", 400, "protocol error"},
    {SDFD_EUNAUTHORIZED, "EUNAUTHORIZED", 401, "missing or wrong bearer token"},
    {SDFD_EMETHOD, "EMETHOD", 405, "method not allowed"},
    {SDFD_ELENGTH, "ELENGTH", 411, "Content-Length required"},
    {SDFD_EBUSY, "EBUSY", 429, "too many requests"},
    {SDFD_EUNAVAILABLE, "EUNAVAILABLE", 503, "service unavailable (loading or shutting down)"},
    {SDFD_ESYNTAX, "ESYNTAX", 400, "malformed request"},
    {SDFD_ENOSPACE, "ENOSPACE", 507, "the store is full"},
};
enum { N_EXPECTED = sizeof expected / sizeof expected[0] };

static int pinned(int code)
{
    for (int i = 0; i < N_EXPECTED; i++)
        if (expected[i].code == code)
            return 1;
    return 0;
}

static void test_table(void)
{
    for (int i = 0; i < N_EXPECTED; i++) {
        int c = expected[i].code;
        CHECK(!strcmp(sdfd_errname(c), expected[i].name), "%d is named %s, not %s", c,
              sdfd_errname(c), expected[i].name);
        CHECK(sdfd_http_status(c) == expected[i].status, "%s answers %d, not %d",
              expected[i].name, sdfd_http_status(c), expected[i].status);
        CHECK(!strcmp(sdfd_strerror(c), expected[i].message), "%s says '%s'", expected[i].name,
              sdfd_strerror(c));
        for (int j = 0; j < i; j++)
            CHECK(expected[j].code != c && strcmp(expected[j].name, expected[i].name),
                  "%s and %s share a value or a name", expected[j].name, expected[i].name);
    }
    int library = 0, server = 0;
#define LIBRARY_CODE(name, value, msg)                                                      \
    library++;                                                                              \
    CHECK(pinned(SDF_##name), "library code %s is not pinned here", #name);                 \
    CHECK(!strcmp(sdfd_strerror(SDF_##name), sdf_strerror(SDF_##name)) &&                   \
              !strcmp(sdfd_errname(SDF_##name), sdf_errname(SDF_##name)),                   \
          "the server renames library code %s", #name);
    SDF_ERRNO_MAP(LIBRARY_CODE)
#undef LIBRARY_CODE
#define SERVER_CODE(name, value, http, msg)                                                 \
    server++;                                                                               \
    CHECK(pinned(SDFD_##name), "server code %s is not pinned here", #name);                 \
    CHECK(!strcmp(sdf_errname(value), "EUNKNOWN"), "server code %s collides with the "      \
          "library's %s", #name, sdf_errname(value));
    SDFD_ERRNO_MAP(SERVER_CODE)
#undef SERVER_CODE
    CHECK(library + server == N_EXPECTED, "%d + %d codes in the tables, %d pinned", library,
          server, N_EXPECTED);
    CHECK(sdfd_http_status(SDF_OK) == 200 && !strcmp(sdfd_errname(SDF_OK), "OK"), "OK");
    CHECK(sdfd_http_status(-999) == 500 && !strcmp(sdfd_errname(-999), "EUNKNOWN") &&
              !strcmp(sdfd_strerror(-999), "unknown error"),
          "unknown code");
}

static const check_case cases[] = {
    {"table", test_table},
};

int main(int argc, char **argv)
{
    return check_main("server_errors", cases, CHECK_COUNT_OF(cases), argc, argv);
}
