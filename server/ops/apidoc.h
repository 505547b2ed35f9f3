/* apidoc.h - docs/openapi.yaml as JSON, generated at build time by server/ops/embedapi.py,
 * which GET /openapi.json serves (opstatus.c). */
#ifndef SDFD_APIDOC_H
#define SDFD_APIDOC_H

#include <stddef.h>

extern const unsigned char sdfd_openapi_json[]; /* sdfd_openapi_json_size bytes, then a NUL */
extern const size_t sdfd_openapi_json_size;

#endif
