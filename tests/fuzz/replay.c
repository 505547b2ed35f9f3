/* replay.c - the test 'fuzz_replay': every harness of tests/fuzz/ run on every file of its
 * seed corpus (corpus/<harness>/) and of its regression inputs (regressions/<harness>/, the
 * inputs that once crashed it), without libFuzzer, in every build (so the address and
 * undefined-behaviour sanitizer build replays them too).
 *
 *   fuzz-replay DIR      DIR: tests/fuzz (meson.build passes it)
 *
 * meson.build compiles each harness with LLVMFuzzerTestOneInput renamed fuzz_<harness> and
 * passes the list of names as FUZZ_HARNESSES. Fails if a harness has no corpus, or if a
 * corpus or regression folder names no harness (a renamed harness would silently lose its
 * inputs). */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define X(name) int fuzz_##name(const uint8_t *data, size_t size);
FUZZ_HARNESSES
#undef X

typedef struct harness {
    const char *name;
    int (*run)(const uint8_t *data, size_t size);
} harness;

#define X(name) {#name, fuzz_##name},
static const harness harnesses[] = {FUZZ_HARNESSES};
#undef X
#define HARNESSES (sizeof harnesses / sizeof harnesses[0])

static int by_name(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* The names of the regular files (or, with dirs, the folders) in `path`, sorted; NULL and
 * *n = 0 if it does not exist. */
static char **list(const char *path, int dirs, size_t *n)
{
    *n = 0;
    DIR *d = opendir(path);
    if (!d)
        return NULL;
    char **names = NULL;
    size_t cap = 0;
    for (struct dirent *e; (e = readdir(d));) {
        if (e->d_name[0] == '.')
            continue;
        char full[4096];
        struct stat st;
        snprintf(full, sizeof full, "%s/%s", path, e->d_name);
        if (stat(full, &st) || (dirs ? !S_ISDIR(st.st_mode) : !S_ISREG(st.st_mode)))
            continue;
        if (*n == cap) {
            cap = cap ? 2 * cap : 64;
            char **grown = realloc(names, cap * sizeof *names);
            if (!grown)
                abort();
            names = grown;
        }
        names[(*n)++] = strdup(e->d_name);
    }
    closedir(d);
    if (names)
        qsort(names, *n, sizeof *names, by_name);
    return names;
}

static void free_list(char **names, size_t n)
{
    for (size_t i = 0; i < n; i++)
        free(names[i]);
    free(names);
}

/* Runs h on every file in dir; returns how many. */
static size_t replay(const harness *h, const char *dir)
{
    size_t n;
    char **files = list(dir, 0, &n);
    for (size_t i = 0; i < n; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, files[i]);
        FILE *f = fopen(path, "rb");
        if (!f) {
            fprintf(stderr, "fuzz_replay: cannot open %s\n", path);
            exit(1);
        }
        fseek(f, 0, SEEK_END);
        long size = ftell(f);
        fseek(f, 0, SEEK_SET);
        uint8_t *data = malloc(size > 0 ? (size_t)size : 1);
        if (!data || (size > 0 && fread(data, 1, (size_t)size, f) != (size_t)size)) {
            fprintf(stderr, "fuzz_replay: cannot read %s\n", path);
            exit(1);
        }
        fclose(f);
        h->run(data, (size_t)size);
        free(data);
    }
    free_list(files, n);
    return n;
}

/* 0 if every folder in DIR/kind names a harness. */
static int check_folders(const char *root, const char *kind)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", root, kind);
    size_t n;
    char **dirs = list(path, 1, &n);
    int bad = 0;
    for (size_t i = 0; i < n; i++) {
        size_t k = 0;
        while (k < HARNESSES && strcmp(harnesses[k].name, dirs[i]))
            k++;
        if (k == HARNESSES) {
            fprintf(stderr, "fuzz_replay: %s/%s names no harness\n", kind, dirs[i]);
            bad = 1;
        }
    }
    free_list(dirs, n);
    return bad;
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: fuzz-replay DIR (tests/fuzz)\n");
        return 2;
    }
    int failed = check_folders(argv[1], "corpus") | check_folders(argv[1], "regressions");
    size_t total = 0;
    for (size_t k = 0; k < HARNESSES; k++) {
        char dir[4096];
        snprintf(dir, sizeof dir, "%s/corpus/%s", argv[1], harnesses[k].name);
        size_t seeds = replay(&harnesses[k], dir);
        snprintf(dir, sizeof dir, "%s/regressions/%s", argv[1], harnesses[k].name);
        size_t regressions = replay(&harnesses[k], dir);
        printf("%-12s %4zu corpus, %3zu regression inputs\n", harnesses[k].name, seeds,
               regressions);
        if (!seeds) {
            fprintf(stderr, "fuzz_replay: %s has no corpus\n", harnesses[k].name);
            failed = 1;
        }
        total += seeds + regressions;
    }
    printf("fuzz_replay: %zu inputs over %zu harnesses\n", total, HARNESSES);
    return failed;
}
