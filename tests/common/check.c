/* check.c - counters and helpers behind check.h. */
#include "check.h"

int check_failures;
int check_count;

int check_finish(const char *name)
{
    printf("%s: %d checks, %d failed\n", name, check_count, check_failures);
    return check_failures ? 1 : 0;
}

const char *data_path(const char *file)
{
    static char path[4096];
    snprintf(path, sizeof path, "%s/%s", SDF_TEST_DATA, file);
    return path;
}
