/* test_names.c - the names of sdf.h's enums (lib/core/names.c): for every value of every
 * enum, name -> value -> name round-trips and the name matches in upper and mixed case;
 * unknown names, the empty name and NULL are SDF_EINVAL and leave *out alone; a value
 * outside an enum is named "?". */
#include <ctype.h>
#include <string.h>

#include "../common/check.h"

/* One enum's pair, seen through int so one loop checks all six. */
typedef struct pair {
    const char *what;
    int count; /* its values are 0 .. count - 1 */
    int (*from_name)(const char *name, int *out);
    const char *(*name)(int value);
} pair;

#define PAIR(what, type, count, from, to)                                                  \
    static int what##_from(const char *name, int *out)                                     \
    {                                                                                      \
        type v = (type)*out;                                                               \
        int rc = from(name, &v);                                                           \
        *out = (int)v;                                                                     \
        return rc;                                                                         \
    }                                                                                      \
    static const char *what##_to(int value) { return to((type)value); }

PAIR(format, sdf_format, 5, sdf_format_from_name, sdf_format_name)
PAIR(sign, sdf_sign_method, 5, sdf_sign_from_name, sdf_sign_name)
PAIR(encoding, sdf_volume_encoding, 2, sdf_encoding_from_name, sdf_encoding_name)
PAIR(normalize, sdf_tdf_normalize, 2, sdf_normalize_from_name, sdf_normalize_name)
PAIR(filter, sdf_volume_filter, 4, sdf_volume_filter_from_name, sdf_volume_filter_name)
PAIR(file, sdf_volume_file, 3, sdf_volume_file_from_name, sdf_volume_file_name)
PAIR(extract, sdf_extract_method, 3, sdf_extract_method_from_name, sdf_extract_method_name)

static void check_pair(const pair *p)
{
    for (int v = 0; v < p->count; v++) {
        const char *name = p->name(v);
        CHECK(name && strcmp(name, "?") && name[0], "%s %d has no name", p->what, v);
        if (!name)
            continue;
        int back = -1;
        CHECK(p->from_name(name, &back) == 0 && back == v, "%s \"%s\" reads back as %d",
              p->what, name, back);
        char upper[64], mixed[64];
        size_t n = strlen(name);
        CHECK(n < sizeof upper, "%s name too long", p->what);
        for (size_t i = 0; i <= n && i < sizeof upper; i++) {
            upper[i] = (char)toupper((unsigned char)name[i]);
            mixed[i] = i % 2 ? upper[i] : name[i];
        }
        back = -1;
        CHECK(p->from_name(upper, &back) == 0 && back == v, "%s \"%s\" not read", p->what,
              upper);
        back = -1;
        CHECK(p->from_name(mixed, &back) == 0 && back == v, "%s \"%s\" not read", p->what,
              mixed);
        for (int w = 0; w < v; w++)
            CHECK(strcasecmp(name, p->name(w)) != 0, "%s %d and %d share a name", p->what, v, w);
        /* A name with a character more, or one less, names nothing. */
        char longer[72];
        snprintf(longer, sizeof longer, "%sx", name);
        int untouched = 77;
        CHECK(p->from_name(longer, &untouched) == SDF_EINVAL && untouched == 77,
              "%s \"%s\" accepted", p->what, longer);
        snprintf(longer, sizeof longer, "%.*s", (int)n - 1, name);
        CHECK(p->from_name(longer, &untouched) == SDF_EINVAL && untouched == 77,
              "%s \"%s\" accepted", p->what, longer);
    }
    int untouched = 77;
    CHECK(p->from_name("bogus", &untouched) == SDF_EINVAL && untouched == 77,
          "%s: an unknown name accepted", p->what);
    CHECK(p->from_name("", &untouched) == SDF_EINVAL && untouched == 77,
          "%s: the empty name accepted", p->what);
    CHECK(p->from_name(NULL, &untouched) == SDF_EINVAL && untouched == 77,
          "%s: NULL accepted", p->what);
    CHECK(!strcmp(p->name(p->count), "?") && !strcmp(p->name(-1), "?"),
          "%s: a value outside the enum is not \"?\"", p->what);
}

static void test_round_trips(void)
{
    const pair pairs[] = {
        {"format", 5, format_from, format_to},
        {"sign", 5, sign_from, sign_to},
        {"encoding", 2, encoding_from, encoding_to},
        {"normalize", 2, normalize_from, normalize_to},
        {"filter", 4, filter_from, filter_to},
        {"file", 3, file_from, file_to},
        {"extract", 3, extract_from, extract_to},
    };
    for (size_t i = 0; i < sizeof pairs / sizeof pairs[0]; i++)
        check_pair(&pairs[i]);
}

/* The spellings the server and the docs use, and the last value of each enum (the counts
 * above must not fall short of an enum). */
static void test_spellings(void)
{
    sdf_format f = SDF_FORMAT_OBJ;
    CHECK(sdf_format_from_name("AUTO", &f) == 0 && f == SDF_FORMAT_AUTO, "format auto");
    CHECK(sdf_format_from_name("Off", &f) == 0 && f == SDF_FORMAT_OFF, "format OFF");
    sdf_sign_method s = SDF_SIGN_AUTO;
    CHECK(sdf_sign_from_name("Winding", &s) == 0 && s == SDF_SIGN_WINDING, "sign case");
    CHECK(sdf_sign_from_name("NONE", &s) == 0 && s == SDF_SIGN_NONE, "sign none");
    sdf_volume_encoding e = SDF_ENCODING_FLOAT32;
    CHECK(sdf_encoding_from_name("PACKED32", &e) == 0 && e == SDF_ENCODING_PACKED32, "packed32");
    sdf_tdf_normalize n = SDF_NORMALIZE_PLANE;
    CHECK(sdf_normalize_from_name("Gradient", &n) == 0 && n == SDF_NORMALIZE_GRADIENT, "gradient");
    sdf_volume_filter vf = SDF_VOLUME_TRILINEAR;
    CHECK(sdf_volume_filter_from_name("NEAREST", &vf) == 0 && vf == SDF_VOLUME_NEAREST, "nearest");
    sdf_volume_file t = SDF_VOLUME_EXR;
    CHECK(sdf_volume_file_from_name("Raw", &t) == 0 && t == SDF_VOLUME_RAW, "raw");
}

static const check_case cases[] = {
    {"round_trips", test_round_trips},
    {"spellings", test_spellings},
};

int main(int argc, char **argv)
{
    return check_main("names", cases, CHECK_COUNT_OF(cases), argc, argv);
}
