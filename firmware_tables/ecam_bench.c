/*
 * ecam_bench.c - timing driver for the ecam C runtime, used by `ecam bench`.
 *
 *   ecam_bench BLOBFILE REPEATS QUERYFILE...
 *
 * Loads one table blob (ecam_table_init), then for each QUERYFILE (a raw array of little-endian
 * int64 master positions, in counts) times REPEATS passes of ecam_table_position over all of its
 * queries, after one untimed warm-up pass, and prints one line per query file:
 *
 *   ns_per_lookup checksum
 *
 * ns_per_lookup is the median over the passes of (pass time / queries), from CLOCK_MONOTONIC.
 * checksum (decimal uint64) folds every position of a pass into two running sums, so the lookups
 * cannot be optimised away and their order matters:
 *
 *   s1 += (uint64)position; s2 += s1;   (mod 2^64, over the queries in file order)
 *   checksum = s1 + s2 * 0x9E3779B97F4A7C15  (mod 2^64)
 *
 * i.e. s1 = sum p[k], s2 = sum (n - k) p[k]; the Python side computes the same from its lookup.
 *
 * Exit status: 0 success, 1 the blob was rejected (prints "error <code> <name>"), 2 usage, I/O or
 * memory error. A host tool: it allocates, unlike the runtime it measures.
 */
#define _POSIX_C_SOURCE 199309L

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ecam_host_io.h"
#include "ecam_table.h"

#define ECAM_BENCH_MAX_REPEATS 1000
#define ECAM_BENCH_MIX UINT64_C(0x9E3779B97F4A7C15)

/* Little-endian int64 from 8 bytes, independent of host byte order and alignment. */
static int64_t ecam_bench_get_i64(const uint8_t *p)
{
    uint64_t u = 0;
    int b;

    for (b = 7; b >= 0; b--) {
        u = (u << 8) | p[b];
    }
    if (u <= (uint64_t)INT64_MAX) {
        return (int64_t)u;
    }
    return (int64_t)(u - (UINT64_C(1) << 63)) - INT64_MAX - 1;
}

/* Monotonic clock in nanoseconds. */
static double ecam_bench_now_ns(void)
{
    struct timespec ts;

    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

/* Comparison for qsort of doubles. */
static int ecam_bench_compare(const void *a, const void *b)
{
    const double x = *(const double *)a;
    const double y = *(const double *)b;

    return (x > y) - (x < y);
}

/* One pass over the queries: position lookups folded into the checksum. */
static uint64_t ecam_bench_pass(const ecam_table *table, const int64_t *queries, size_t count)
{
    uint64_t s1 = 0;
    uint64_t s2 = 0;
    size_t k;

    for (k = 0; k < count; k++) {
        const int32_t position = ecam_table_position(table, queries[k]);
        s1 += (uint64_t)(int64_t)position;
        s2 += s1;
    }
    return s1 + s2 * ECAM_BENCH_MIX;
}

/* Times one query file; prints "ns_per_lookup checksum". Returns 0 or 2 (I/O, memory). */
static int ecam_bench_file(const ecam_table *table, const char *path, int repeats)
{
    size_t len = 0;
    uint8_t *raw = ecam_host_read_file(path, &len);
    int64_t *queries;
    double *times;
    size_t count;
    size_t k;
    uint64_t checksum;
    int r;

    if (raw == NULL) {
        fprintf(stderr, "ecam_bench: cannot read %s\n", path);
        return 2;
    }
    count = len / 8u;
    if (count == 0 || len % 8u != 0) {
        fprintf(stderr, "ecam_bench: %s should hold a non-empty array of int64 (%lu bytes)\n",
                path, (unsigned long)len);
        free(raw);
        return 2;
    }
    queries = malloc(count * sizeof *queries);
    times = malloc((size_t)repeats * sizeof *times);
    if (queries == NULL || times == NULL) {
        fprintf(stderr, "ecam_bench: out of memory\n");
        free(raw);
        free(queries);
        free(times);
        return 2;
    }
    for (k = 0; k < count; k++) {
        queries[k] = ecam_bench_get_i64(raw + 8u * k);
    }
    free(raw);
    checksum = ecam_bench_pass(table, queries, count); /* warm-up: caches, branch predictors */
    for (r = 0; r < repeats; r++) {
        const double start = ecam_bench_now_ns();
        const uint64_t sum = ecam_bench_pass(table, queries, count);
        times[r] = (ecam_bench_now_ns() - start) / (double)count;
        if (sum != checksum) {
            fprintf(stderr, "ecam_bench: checksum changed between passes\n");
            free(queries);
            free(times);
            return 2;
        }
    }
    qsort(times, (size_t)repeats, sizeof *times, ecam_bench_compare);
    printf("%.4f %" PRIu64 "\n",
           repeats % 2 ? times[repeats / 2] : 0.5 * (times[repeats / 2 - 1] + times[repeats / 2]),
           checksum);
    free(queries);
    free(times);
    return 0;
}

/* Entry point: ecam_bench BLOBFILE REPEATS QUERYFILE... */
int main(int argc, char **argv)
{
    ecam_table table;
    uint8_t *blob;
    size_t len = 0;
    char *end = NULL;
    long repeats;
    int status;
    int rc = 0;
    int i;

    if (argc < 4) {
        fprintf(stderr, "usage: ecam_bench BLOBFILE REPEATS QUERYFILE...\n");
        return 2;
    }
    repeats = strtol(argv[2], &end, 10);
    if (end == argv[2] || *end != '\0' || repeats < 1 || repeats > ECAM_BENCH_MAX_REPEATS) {
        fprintf(stderr, "ecam_bench: REPEATS %s should be an integer in 1..%d\n", argv[2],
                ECAM_BENCH_MAX_REPEATS);
        return 2;
    }
    blob = ecam_host_read_file(argv[1], &len);
    if (blob == NULL) {
        fprintf(stderr, "ecam_bench: cannot read %s\n", argv[1]);
        return 2;
    }
    status = ecam_table_init(&table, blob, len);
    if (status != ECAM_OK) {
        printf("error %d %s\n", status, ecam_status_name(status));
        free(blob);
        return 1;
    }
    for (i = 3; i < argc && rc == 0; i++) {
        rc = ecam_bench_file(&table, argv[i], (int)repeats);
    }
    fflush(stdout);
    free(blob);
    return rc;
}
