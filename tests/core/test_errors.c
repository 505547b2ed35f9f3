/* test_errors.c - the library's error table: every code is negative and has a distinct name
 * and a message; unknown codes, among them the values the table leaves to the layers above
 * (-13..-19), are named EUNKNOWN; names of enums round-trip. HTTP statuses are the server's
 * (tests/server/test_errors.c). */
#include <string.h>

#include "../common/check.h"

static void test_table(void)
{
    static const int codes[] = {
#define CODE(name, value, msg) SDF_##name,
        SDF_ERRNO_MAP(CODE)
#undef CODE
    };
    size_t n = sizeof codes / sizeof codes[0];
    for (size_t i = 0; i < n; i++) {
        CHECK(codes[i] < 0, "code %d is not negative", codes[i]);
        CHECK(strcmp(sdf_strerror(codes[i]), "unknown error") != 0, "no message for %d", codes[i]);
        CHECK(codes[i] > -13 || codes[i] < -19, "%s takes %d, a value left to the server",
              sdf_errname(codes[i]), codes[i]);
        for (size_t j = 0; j < i; j++)
            CHECK(codes[i] != codes[j] && strcmp(sdf_errname(codes[i]), sdf_errname(codes[j])),
                  "duplicate code or name %d", codes[i]);
    }
    CHECK(!strcmp(sdf_errname(0), "OK") && !strcmp(sdf_strerror(0), "success"), "OK");
    for (int err = -19; err <= -13; err++)
        CHECK(!strcmp(sdf_errname(err), "EUNKNOWN") && !strcmp(sdf_strerror(err), "unknown error"),
              "the library names %d", err);
    CHECK(!strcmp(sdf_strerror(-999), "unknown error") && !strcmp(sdf_errname(-999), "EUNKNOWN"),
          "unknown code");
    CHECK(!strcmp(sdf_errname(SDF_ENOTFOUND), "ENOTFOUND") &&
              !strcmp(sdf_strerror(SDF_ECANCELED), "canceled"),
          "names and messages");
    for (int s = SDF_SIGN_AUTO; s <= SDF_SIGN_NONE; s++) {
        sdf_sign_method back;
        CHECK(sdf_sign_from_name(sdf_sign_name((sdf_sign_method)s), &back) == 0 && (int)back == s,
              "sign name %d", s);
    }
    sdf_sign_method m;
    CHECK(sdf_sign_from_name("bogus", &m) == SDF_EINVAL && sdf_sign_from_name(NULL, &m) == SDF_EINVAL,
          "bad sign name accepted");
}

static const check_case cases[] = {
    {"table", test_table},
};

int main(int argc, char **argv)
{
    return check_main("errors", cases, CHECK_COUNT_OF(cases), argc, argv);
}
