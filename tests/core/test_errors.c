/* test_errors.c - the error table: every code has a distinct name, a message and an HTTP
 * status in the 4xx/5xx range; unknown codes are handled; names of enums round-trip. */
#include <string.h>

#include "../common/check.h"

int main(void)
{
    static const int codes[] = {
#define CODE(name, value, http, msg) SDF_##name,
        SDF_ERRNO_MAP(CODE)
#undef CODE
    };
    size_t n = sizeof codes / sizeof codes[0];
    for (size_t i = 0; i < n; i++) {
        CHECK(codes[i] < 0, "code %d is not negative", codes[i]);
        CHECK(strcmp(sdf_strerror(codes[i]), "unknown error") != 0, "no message for %d", codes[i]);
        int http = sdf_http_status(codes[i]);
        CHECK(http >= 400 && http < 600, "%s maps to HTTP %d", sdf_errname(codes[i]), http);
        for (size_t j = 0; j < i; j++)
            CHECK(codes[i] != codes[j] && strcmp(sdf_errname(codes[i]), sdf_errname(codes[j])),
                  "duplicate code or name %d", codes[i]);
    }
    CHECK(sdf_http_status(SDF_OK) == 200 && !strcmp(sdf_errname(0), "OK"), "OK");
    CHECK(!strcmp(sdf_strerror(-999), "unknown error") && sdf_http_status(-999) == 500 &&
              !strcmp(sdf_errname(-999), "EUNKNOWN"),
          "unknown code");
    CHECK(sdf_http_status(SDF_ENOTFOUND) == 404 && sdf_http_status(SDF_ELIMIT) == 413 &&
              sdf_http_status(SDF_EFORMAT) == 415,
          "statuses");
    for (int s = SDF_SIGN_AUTO; s <= SDF_SIGN_NONE; s++) {
        sdf_sign_method back;
        CHECK(sdf_sign_from_name(sdf_sign_name((sdf_sign_method)s), &back) == 0 && (int)back == s,
              "sign name %d", s);
    }
    sdf_sign_method m;
    CHECK(sdf_sign_from_name("bogus", &m) == SDF_EINVAL && sdf_sign_from_name(NULL, &m) == SDF_EINVAL,
          "bad sign name accepted");
    return check_finish("test_errors");
}
