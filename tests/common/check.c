/* check.c - counters and the case runner behind check.h. */
#include "check.h"

#include <string.h>

_Atomic int check_failures;
_Atomic int check_count;

static void list(FILE *out, const check_case *cases, size_t n)
{
    for (size_t i = 0; i < n; i++)
        fprintf(out, "%s\n", cases[i].name);
}

static const check_case *find(const check_case *cases, size_t n, const char *name)
{
    for (size_t i = 0; i < n; i++)
        if (!strcmp(cases[i].name, name))
            return &cases[i];
    return NULL;
}

/* Runs one case; returns 1 if it ran no CHECK. */
static int run_case(const char *program, const check_case *c)
{
    int count = check_count, failures = check_failures;
    c->run();
    int ran = check_count - count, failed = check_failures - failures;
    printf("%s %s: %d checks, %d failed\n", program, c->name, ran, failed);
    fflush(stdout);
    if (ran == 0)
        fprintf(stderr, "%s %s: the case ran no CHECK\n", program, c->name);
    return ran == 0;
}

int check_main(const char *program, const check_case *cases, size_t n, int argc, char **argv)
{
    if (argc == 2 && !strcmp(argv[1], "--list")) {
        list(stdout, cases, n);
        return 0;
    }
    for (int a = 1; a < argc; a++)
        if (!find(cases, n, argv[a])) {
            fprintf(stderr, "%s: no case named '%s'; the cases are:\n", program, argv[a]);
            list(stderr, cases, n);
            return 2;
        }
    int empty = 0;
    if (argc < 2)
        for (size_t i = 0; i < n; i++)
            empty += run_case(program, &cases[i]);
    for (int a = 1; a < argc; a++)
        empty += run_case(program, find(cases, n, argv[a]));
    printf("%s: %d checks, %d failed\n", program, (int)check_count, (int)check_failures);
    if (empty)
        fprintf(stderr, "%s: %d case(s) ran no CHECK\n", program, empty);
    return check_failures || empty || n == 0 ? 1 : 0;
}

const char *data_path(const char *file)
{
    static char path[4096];
    snprintf(path, sizeof path, "%s/%s", SDF_TEST_DATA, file);
    return path;
}

sdf_mesh *load_data_mesh(const char *file)
{
    sdf_mesh *mesh = NULL;
    sdf_diag diag;
    int rc = sdf_mesh_load_file(data_path(file), NULL, &mesh, &diag);
    CHECK(rc == 0, "%s: %s", file, diag.message);
    return rc ? NULL : mesh;
}
