/* names.c - the names of sdf.h's enums: every *_from_name and *_name pair.
 *
 * Each enum's names are one X-macro list, and one macro makes both functions of every pair
 * from its list, so that all of them read and write the same spellings the same way: a name
 * matches whatever its case (strcasecmp), NULL and unknown names are SDF_EINVAL with *out
 * left as it was, and a value outside the enum is named "?". Every value has a name, so
 * name -> value -> name round-trips (tests/core/test_names.c). */
#include <stddef.h>
#include <strings.h>

#include "sdf/sdf.h"

#define FORMAT_NAMES(X)                                                                    \
    X(SDF_FORMAT_AUTO, "auto") X(SDF_FORMAT_OBJ, "obj") X(SDF_FORMAT_PLY, "ply")            \
    X(SDF_FORMAT_STL, "stl") X(SDF_FORMAT_OFF, "off")
#define SIGN_NAMES(X)                                                                      \
    X(SDF_SIGN_AUTO, "auto") X(SDF_SIGN_PSEUDONORMAL, "pseudonormal")                       \
    X(SDF_SIGN_WINDING, "winding") X(SDF_SIGN_RAYCAST, "raycast") X(SDF_SIGN_NONE, "none")
#define ENCODING_NAMES(X) X(SDF_ENCODING_FLOAT32, "float32") X(SDF_ENCODING_PACKED32, "packed32")
#define NORMALIZE_NAMES(X) X(SDF_NORMALIZE_PLANE, "plane") X(SDF_NORMALIZE_GRADIENT, "gradient")
#define FILTER_NAMES(X)                                                                      \
    X(SDF_VOLUME_DEFAULT, "default") X(SDF_VOLUME_NEAREST, "nearest")                        \
    X(SDF_VOLUME_TRILINEAR, "trilinear") X(SDF_VOLUME_HERMITE, "hermite")
#define EXTRACT_NAMES(X)                                                                   \
    X(SDF_EXTRACT_AUTO, "auto") X(SDF_EXTRACT_MARCHING_CUBES, "marching_cubes")               \
    X(SDF_EXTRACT_DUAL, "dual_contouring")
#define FILE_NAMES(X) X(SDF_VOLUME_EXR, "exr") X(SDF_VOLUME_NPY, "npy") X(SDF_VOLUME_RAW, "raw")

#define NAME_ROW(value, name) {value, name},

/* `type`'s table and its two functions, from_name and to_name, from the X-macro LIST. */
#define NAME_PAIR(type, from_name, to_name, LIST)                                          \
    static const struct {                                                                  \
        type value;                                                                        \
        const char *name;                                                                  \
    } to_name##_table[] = {LIST(NAME_ROW)};                                                \
                                                                                           \
    int from_name(const char *name, type *out)                                             \
    {                                                                                      \
        for (size_t i = 0; name && i < sizeof to_name##_table / sizeof *to_name##_table; i++) \
            if (!strcasecmp(name, to_name##_table[i].name)) {                              \
                *out = to_name##_table[i].value;                                           \
                return 0;                                                                  \
            }                                                                              \
        return SDF_EINVAL;                                                                 \
    }                                                                                      \
                                                                                           \
    const char *to_name(type value)                                                        \
    {                                                                                      \
        for (size_t i = 0; i < sizeof to_name##_table / sizeof *to_name##_table; i++)      \
            if (to_name##_table[i].value == value)                                         \
                return to_name##_table[i].name;                                            \
        return "?";                                                                        \
    }

NAME_PAIR(sdf_format, sdf_format_from_name, sdf_format_name, FORMAT_NAMES)
NAME_PAIR(sdf_sign_method, sdf_sign_from_name, sdf_sign_name, SIGN_NAMES)
NAME_PAIR(sdf_volume_encoding, sdf_encoding_from_name, sdf_encoding_name, ENCODING_NAMES)
NAME_PAIR(sdf_tdf_normalize, sdf_normalize_from_name, sdf_normalize_name, NORMALIZE_NAMES)
NAME_PAIR(sdf_volume_filter, sdf_volume_filter_from_name, sdf_volume_filter_name, FILTER_NAMES)
NAME_PAIR(sdf_volume_file, sdf_volume_file_from_name, sdf_volume_file_name, FILE_NAMES)
NAME_PAIR(sdf_extract_method, sdf_extract_method_from_name, sdf_extract_method_name,
          EXTRACT_NAMES)
