/* test_lanes.c - the eight-lane helpers the walks lean on (lib/points/lanes.h) against slow,
 * obvious ones: the sorting network that orders a wide node's children (every permutation
 * of eight distinct keys, and random keys full of repeats and of the INT32_MAX that marks a
 * child out of reach, against qsort), and the OR of a vector's lanes (one bit at a time). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "points/lanes.h"

static int by_value(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* Sort `keys` both ways; CHECK they agree. */
static void check_sort(const int32_t keys[8])
{
    int32_t want[8];
    memcpy(want, keys, sizeof want);
    qsort(want, 8, sizeof want[0], by_value);
    sdf__v8i v;
    memcpy(&v, keys, sizeof v);
    v = sdf__v8i_sort(v);
    int same = 1;
    for (int i = 0; i < 8; i++)
        same &= v[i] == want[i];
    CHECK(same, "sorted %d %d %d %d %d %d %d %d, want %d %d %d %d %d %d %d %d", v[0], v[1],
          v[2], v[3], v[4], v[5], v[6], v[7], want[0], want[1], want[2], want[3], want[4],
          want[5], want[6], want[7]);
}

/* Every permutation of 0..7 (Heap's algorithm), keys spread over the int range. */
static int all_permutations(void)
{
    int32_t a[8];
    int c[8] = {0}, failures = check_failures, count = 1;
    for (int i = 0; i < 8; i++)
        a[i] = (int32_t)(i * 250000000) - 900000000;
    check_sort(a);
    for (int i = 1; i < 8;) {
        if (c[i] < i) {
            int j = i % 2 ? c[i] : 0;
            int32_t t = a[j];
            a[j] = a[i], a[i] = t;
            check_sort(a);
            count++;
            c[i]++;
            i = 1;
        } else {
            c[i++] = 0;
        }
    }
    CHECK(count == 40320, "%d permutations", count);
    return check_failures - failures;
}

/* Keys as the walk makes them: a distance's bits with a slot in the low three, or
 * INT32_MAX; drawn from a few values so repeats are common. */
static void random_keys(void)
{
    uint64_t state = 12345;
    for (int round = 0; round < 100000; round++) {
        int32_t keys[8];
        for (int i = 0; i < 8; i++) {
            state = state * 6364136223846793005u + 1442695040888963407u;
            uint32_t r = (uint32_t)(state >> 33);
            keys[i] = r % 5 == 0 ? INT32_MAX : (int32_t)((r % 7) << 3 | (uint32_t)i % 4);
        }
        check_sort(keys);
    }
}

static void or_lanes(void)
{
    for (int lane = 0; lane < 8; lane++)
        for (int bit = 0; bit < 32; bit++) {
            sdf__v8i v = {0};
            v[lane] = (int32_t)(1u << bit);
            CHECK(sdf__v8i_or_lanes(v) == 1u << bit, "lane %d bit %d", lane, bit);
            CHECK(sdf__v8i_any(v), "lane %d bit %d not seen", lane, bit);
        }
    sdf__v8i mixed = {1, 2, 4, 8, 16, 32, 64, (int32_t)0x80000000u};
    CHECK(sdf__v8i_or_lanes(mixed) == 0x8000007fu, "%x", sdf__v8i_or_lanes(mixed));
    CHECK(!sdf__v8i_any((sdf__v8i){0}), "empty mask seen as set");
}

static void test_permutations(void)
{
    CHECK(all_permutations() == 0, "the network misorders some permutation");
}

static const check_case cases[] = {
    {"permutations", test_permutations},
    {"random_keys", random_keys},
    {"or_lanes", or_lanes},
};

int main(int argc, char **argv)
{
    return check_main("lanes", cases, CHECK_COUNT_OF(cases), argc, argv);
}
