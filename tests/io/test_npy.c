/* test_npy.c - the .npy codec: headers we write parse back; NumPy's own layouts (versions
 * 1-3, float64, 1-D) parse; every truncated prefix and each malformed header is refused
 * with a message; sdf_npy_parse_numeric takes integers too. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"

static size_t make_npy(char *dst, const char *dict, int version, size_t data_bytes)
{
    size_t len_bytes = version == 1 ? 2 : 4, n = strlen(dict);
    size_t total = (10 + (len_bytes - 2) + n + 1 + 63) / 64 * 64;
    size_t header = total - 8 - len_bytes;
    memcpy(dst, "\x93NUMPY", 6);
    dst[6] = (char)version;
    dst[7] = 0;
    for (size_t i = 0; i < len_bytes; i++)
        dst[8 + i] = (char)(header >> (8 * i));
    memcpy(dst + 8 + len_bytes, dict, n);
    memset(dst + 8 + len_bytes + n, ' ', header - n - 1);
    dst[total - 1] = '\n';
    memset(dst + total, 0, data_bytes);
    return total + data_bytes;
}

static void test_headers(void)
{
    char buf[4096];
    sdf_npy_info info;
    sdf_diag diag;
    size_t shape[2] = {5, 3};
    long h = sdf_npy_write_header(buf, sizeof buf, 2, shape);
    CHECK(h > 0 && h % 64 == 0, "header length %ld", h);
    memset(buf + h, 0, 60);
    CHECK(sdf_npy_parse(buf, (size_t)h + 60, &info, &diag) == 0, "%s", diag.message);
    CHECK(info.dtype == SDF_NPY_F32 && info.ndim == 2 && info.shape[0] == 5 && info.shape[1] == 3 &&
              info.data_offset == (size_t)h && info.data_bytes == 60,
          "round trip");
    for (size_t len = 0; len < (size_t)h + 60; len++)
        CHECK(sdf_npy_parse(buf, len, &info, &diag) != 0 && diag.message[0], "prefix %zu accepted", len);
    CHECK(sdf_npy_parse(buf, (size_t)h + 64, &info, &diag) == SDF_EPARSE, "trailing bytes accepted");
    size_t one[1] = {7};
    h = sdf_npy_write_header(buf, sizeof buf, 1, one);
    CHECK(h > 0 && strstr(buf + 10, "(7,)") != NULL, "1-D shape spelled (7,)");
    CHECK(sdf_npy_write_header(buf, 16, 2, shape) == SDF_ELIMIT, "small buffer");

    size_t n = make_npy(buf, "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 3), }", 2, 96);
    CHECK(sdf_npy_parse(buf, n, &info, &diag) == 0 && info.dtype == SDF_NPY_F64 &&
              info.shape[0] == 4, "version 2 float64: %s", diag.message);
    n = make_npy(buf, "{'shape':(2,3),'fortran_order':False,'descr':'<f4'}", 3, 24);
    CHECK(sdf_npy_parse(buf, n, &info, &diag) == 0, "version 3, other key order: %s", diag.message);

    static const struct { const char *dict; int code; } bad[] = {  /* NOLINT */
        {"{'descr': '>f4', 'fortran_order': False, 'shape': (2, 3), }", SDF_EFORMAT},
        {"{'descr': '<i4', 'fortran_order': False, 'shape': (2, 3), }", SDF_EFORMAT},
        {"{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3), }", SDF_EFORMAT},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': [2, 3], }", SDF_EPARSE},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, x), }", SDF_EPARSE},
        {"{'descr': '<f4', 'fortran_order': False, }", SDF_EPARSE},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (1, 1, 1, 1, 1), }", SDF_ELIMIT},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999, 3), }", SDF_ETRUNC},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999999, 3), }", SDF_ELIMIT},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (4294967296, 4294967296, 4294967296), }", SDF_ETRUNC},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        n = make_npy(buf, bad[i].dict, 1, 24);
        int rc = sdf_npy_parse(buf, n, &info, &diag);
        CHECK(rc == bad[i].code, "%s: got %s (%s)", bad[i].dict, sdf_errname(rc), diag.message);
    }
    n = make_npy(buf, "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }", 1, 24);
    buf[8] = (char)0xff, buf[9] = 0x7f; /* header length past the end */
    CHECK(sdf_npy_parse(buf, n, &info, &diag) == SDF_ETRUNC, "header length: %s", diag.message);
    buf[6] = 9;
    CHECK(sdf_npy_parse(buf, n, &info, &diag) == SDF_EFORMAT, "version 9 accepted");
    CHECK(sdf_npy_parse("GIF89a....", 10, &info, &diag) == SDF_EFORMAT, "bad magic accepted");
}

/* sdf_npy_parse_numeric: integers of every size, as NumPy spells them; floats as before. */
static void test_numeric(void)
{
    char buf[4096];
    sdf_npy_info info;
    sdf_diag diag;
    static const struct { const char *descr; char kind; size_t size; } ok[] = {  /* NOLINT */
        {"<i8", 'i', 8}, {"<i4", 'i', 4}, {"<i2", 'i', 2}, {"|i1", 'i', 1}, {"<u8", 'u', 8},
        {"<u4", 'u', 4}, {"<u2", 'u', 2}, {"|u1", 'u', 1}, {"<f4", 'f', 4}, {"<f8", 'f', 8},
    };
    for (size_t i = 0; i < sizeof ok / sizeof ok[0]; i++) {
        char dict[96];
        snprintf(dict, sizeof dict, "{'descr': '%s', 'fortran_order': False, 'shape': (2, 3), }",
                 ok[i].descr);
        size_t n = make_npy(buf, dict, 1, 6 * ok[i].size);
        CHECK(sdf_npy_parse_numeric(buf, n, &info, &diag) == 0 && info.kind == ok[i].kind &&
                  info.itemsize == ok[i].size && info.data_bytes == 6 * ok[i].size &&
                  (info.kind == 'f') == (info.dtype != 0),
              "%s: %s", ok[i].descr, diag.message);
        CHECK((sdf_npy_parse(buf, n, &info, &diag) == 0) == (ok[i].kind == 'f'),
              "sdf_npy_parse and %s", ok[i].descr);
        CHECK(sdf_npy_parse_numeric(buf, n - 1, &info, &diag) == SDF_ETRUNC, "%s cut short",
              ok[i].descr);
    }
    static const char *const bad[] = {">i8", "<i3", "<b1", "|i8", "<c8", "<U4", "|O"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char dict[96];
        snprintf(dict, sizeof dict, "{'descr': '%s', 'fortran_order': False, 'shape': (2, 3), }",
                 bad[i]);
        size_t n = make_npy(buf, dict, 1, 48);
        CHECK(sdf_npy_parse_numeric(buf, n, &info, &diag) == SDF_EFORMAT &&
                  strstr(diag.message, "integer"), "%s accepted: %s", bad[i], diag.message);
    }
}

static const check_case cases[] = {
    {"headers", test_headers},
    {"numeric", test_numeric},
};

int main(int argc, char **argv)
{
    return check_main("npy", cases, CHECK_COUNT_OF(cases), argc, argv);
}
