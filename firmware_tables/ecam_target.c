/*
 * ecam_target.c - driver of the ecam runtime on cross targets (Cortex-M4 under QEMU with
 * semihosting, PPC32, i386, armhf under qemu-user) and for instruction counts. Files in, files
 * out, byte order fixed (little-endian), so the host compares the results whatever the target.
 *
 *   ecam_target lookup BLOB QUERIES OUT  QUERIES: int64 LE; OUT: (position, slope) int32 LE pairs.
 *                                        Every output is also checked against ecam_table_position,
 *                                        ecam_table_slope, the one-output lookups and the expanded
 *                                        form (ecam_poly_position); the blob is also loaded at an
 *                                        odd address and must answer the same.
 *   ecam_target status BLOB...           one line "<status>" per blob (ecam_table_init).
 *   ecam_target count BLOB WHAT QUERIES...
 *                                        WHAT = runtime | minimal | poly | expanded | q16:
 *                                        position lookups only, for an instruction counter;
 *                                        prints "<calls> <checksum>" per query file, in order.
 *                                        runtime: ecam_table_position; poly: ecam_poly_position
 *                                        (the expanded form); minimal: ecam_minimal_<degree> on the
 *                                        payload read into native arrays (no ecam_table_init);
 *                                        expanded and q16: ecam_minimal_expanded_<degree> and
 *                                        ecam_minimal_q16_<degree> on precomputed coefficients
 *                                        (the expansion's int64 words; those shifted to whole
 *                                        counts as int32).
 *   ecam_target stack BLOB QUERIES       largest stack (bytes) one ecam_table_position, one
 *                                        ecam_table_slope and one ecam_table_lookup call used, by
 *                                        stack painting (ARM M-profile only; "unsupported"
 *                                        elsewhere), and sizeof(ecam_table), sizeof(ecam_table_pair).
 *
 * Exit status: 0 success, 1 blob rejected (lookup/count/stack) or a self-check failed, 2 usage,
 * I/O or memory error. A test tool: it allocates, unlike the runtime.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ecam_host_io.h"
#include "ecam_minimal.h"
#include "ecam_table.h"

#if defined(__ARM_ARCH_7EM__) || defined(__ARM_ARCH_7M__)
#define ECAM_TARGET_PAINT 1
#else
#define ECAM_TARGET_PAINT 0
#endif

static int64_t get_i64(const unsigned char *p)
{
    uint64_t u = 0;
    int b;

    for (b = 7; b >= 0; b--) {
        u = (u << 8) | p[b];
    }
    return u <= (uint64_t)INT64_MAX ? (int64_t)u : (int64_t)(u - (UINT64_C(1) << 63)) - INT64_MAX - 1;
}

static int32_t get_i32(const unsigned char *p)
{
    const uint32_t u = (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
                       ((uint32_t)p[3] << 24);

    return u <= (uint32_t)INT32_MAX ? (int32_t)u : (int32_t)(u - UINT32_C(0x80000000)) - INT32_MAX - 1;
}

static void put_i32(unsigned char *p, int32_t v)
{
    const uint32_t u = (uint32_t)v;

    p[0] = (unsigned char)u;
    p[1] = (unsigned char)(u >> 8);
    p[2] = (unsigned char)(u >> 16);
    p[3] = (unsigned char)(u >> 24);
}

/* Blob and queries of one run. */
typedef struct {
    unsigned char *blob_storage;
    unsigned char *query_bytes;
    size_t blob_len;
    size_t count;
    ecam_table table;
} run_input;

static int load(run_input *in, const char *blob_path, const char *query_path)
{
    size_t len = 0;
    int status;

    in->blob_storage = ecam_host_read_file(blob_path, &in->blob_len);
    in->query_bytes = query_path == NULL ? NULL : ecam_host_read_file(query_path, &len);
    if (in->blob_storage == NULL || (query_path != NULL && in->query_bytes == NULL) || len % 8u) {
        fprintf(stderr, "ecam_target: cannot read %s\n", in->blob_storage == NULL ? blob_path : query_path);
        return 2;
    }
    in->count = len / 8u;
    status = ecam_table_init(&in->table, in->blob_storage, in->blob_len);
    if (status != ECAM_OK) {
        printf("error %d %s\n", status, ecam_status_name(status));
        return 1;
    }
    return 0;
}

static int do_lookup(const char *blob_path, const char *query_path, const char *out_path)
{
    run_input in;
    ecam_table odd;
    ecam_poly poly;
    int64_t *words;
    unsigned char *shifted;
    unsigned char *out;
    FILE *f;
    size_t k;
    int rc = load(&in, blob_path, query_path);

    if (rc != 0) {
        return rc;
    }
    shifted = malloc(in.blob_len + 1u);
    out = malloc(in.count * 8u + 1u);
    if (shifted == NULL || out == NULL) {
        return 2;
    }
    memcpy(shifted + 1, in.blob_storage, in.blob_len); /* an odd address */
    if (ecam_table_init(&odd, shifted + 1, in.blob_len) != ECAM_OK) {
        fprintf(stderr, "ecam_target: the blob at an odd address was rejected\n");
        return 1;
    }
    words = malloc(ecam_poly_bytes(&in.table) + 8u);
    if (words == NULL || ecam_poly_init(&poly, &in.table, words, ecam_poly_bytes(&in.table)) != ECAM_OK) {
        fprintf(stderr, "ecam_target: the expansion failed\n");
        return 1;
    }
    for (k = 0; k < in.count; k++) {
        const int64_t m = get_i64(in.query_bytes + 8u * k);
        int32_t position;
        int32_t slope;
        int32_t p2 = 0;
        int32_t s2 = 0;

        ecam_table_lookup(&in.table, m, &position, &slope);
        ecam_table_lookup(&in.table, m, &p2, NULL);
        ecam_table_lookup(&in.table, m, NULL, &s2);
        if (p2 != position || s2 != slope || ecam_table_position(&in.table, m) != position ||
            ecam_table_slope(&in.table, m) != slope || ecam_table_position(&odd, m) != position ||
            ecam_poly_position(&poly, m) != position) {
            fprintf(stderr, "ecam_target: the lookups of master %lld disagree\n", (long long)m);
            return 1;
        }
        put_i32(out + 8u * k, position);
        put_i32(out + 8u * k + 4u, slope);
    }
    f = fopen(out_path, "wb");
    if (f == NULL || fwrite(out, 1, in.count * 8u, f) != in.count * 8u || fclose(f) != 0) {
        fprintf(stderr, "ecam_target: cannot write %s\n", out_path);
        return 2;
    }
    free(out);
    free(words);
    free(shifted);
    free(in.blob_storage);
    free(in.query_bytes);
    return 0;
}

static int do_status(int count, char **paths)
{
    int i;

    for (i = 0; i < count; i++) {
        ecam_table t;
        size_t len = 0;
        unsigned char *blob = ecam_host_read_file(paths[i], &len);

        if (blob == NULL) {
            fprintf(stderr, "ecam_target: cannot read %s\n", paths[i]);
            return 2;
        }
        printf("%d\n", ecam_table_init(&t, blob, len));
        free(blob);
    }
    return 0;
}

/* The payload as aligned native int32 arrays, for the minimal lookups. */
static int32_t *native_arrays(const unsigned char *blob, size_t len, uint32_t *points)
{
    const size_t words = (len - ECAM_HEADER_BYTES) / 4u;
    int32_t *arrays = malloc(words * sizeof *arrays + 4u);
    size_t k;

    *points = (uint32_t)get_i32(blob + 16);
    for (k = 0; arrays != NULL && k < words; k++) {
        arrays[k] = get_i32(blob + ECAM_HEADER_BYTES + 4u * k);
    }
    return arrays;
}

/* What one count runs. */
typedef struct {
    const ecam_table *table;  /* runtime */
    const ecam_poly *poly;    /* poly */
    const int32_t *arrays;    /* minimal: native payload; q16: int32 coefficients */
    const int64_t *words;     /* expanded: the expansion's words */
    uint32_t points;
    unsigned degree;
    int q16;
} count_subject;

static int32_t count_one(const count_subject *c, int64_t query)
{
    const uint32_t m = (uint32_t)query; /* the minimal lookups: inside [0, M) by contract */

    if (c->table != NULL) {
        return ecam_table_position(c->table, query);
    }
    if (c->poly != NULL) {
        return ecam_poly_position(c->poly, query);
    }
    if (c->words != NULL) {
        return c->degree == 1u ? ecam_minimal_expanded_linear(c->words, m)
               : c->degree == 3u ? ecam_minimal_expanded_cubic(c->words, m)
                                 : ecam_minimal_expanded_quintic(c->words, m);
    }
    if (c->q16) {
        return c->degree == 1u ? ecam_minimal_q16_linear(c->arrays, m)
               : c->degree == 3u ? ecam_minimal_q16_cubic(c->arrays, m)
                                 : ecam_minimal_q16_quintic(c->arrays, m);
    }
    return c->degree == 1u ? ecam_minimal_linear(c->arrays, m)
           : c->degree == 3u ? ecam_minimal_cubic(c->arrays, c->arrays + c->points, m)
                             : ecam_minimal_quintic(c->arrays, c->arrays + c->points, c->arrays + 2u * c->points, m);
}

/* One query file's position lookups through one subject. */
static int count_file(const char *path, const count_subject *subject)
{
    size_t len = 0;
    unsigned char *bytes = ecam_host_read_file(path, &len);
    int64_t *queries;
    uint64_t checksum = 0;
    size_t count;
    size_t k;

    if (bytes == NULL || len % 8u) {
        fprintf(stderr, "ecam_target: cannot read %s\n", path);
        return 2;
    }
    count = len / 8u;
    queries = malloc(count * sizeof *queries + 8u);
    if (queries == NULL) {
        return 2;
    }
    for (k = 0; k < count; k++) {
        queries[k] = get_i64(bytes + 8u * k);
    }
    for (k = 0; k < count; k++) {
        checksum = checksum * 31u + (uint32_t)count_one(subject, queries[k]);
    }
    printf("%lu %08lx%08lx\n", (unsigned long)count, (unsigned long)(checksum >> 32),
           (unsigned long)(checksum & 0xFFFFFFFFu));
    free(queries);
    free(bytes);
    return 0;
}

/* floor(x / 2^s) for the int32 coefficients of q16. */
static int64_t asr64(int64_t x, unsigned s)
{
    return x >= 0 ? x >> s : ~(~x >> s);
}

static int do_count(const char *blob_path, const char *what, int files, char **query_paths)
{
    size_t len = 0;
    unsigned char *blob = ecam_host_read_file(blob_path, &len);
    ecam_table table;
    ecam_poly poly;
    int32_t *arrays = NULL;
    int32_t *q16 = NULL;
    int64_t *words = NULL;
    count_subject subject;
    int rc = 0;
    int i;

    memset(&subject, 0, sizeof subject);
    if (blob == NULL || len < ECAM_HEADER_BYTES) {
        fprintf(stderr, "ecam_target: cannot read %s\n", blob_path);
        return 2;
    }
    subject.degree = blob[8];
    if (strcmp(what, "minimal") == 0) {
        arrays = native_arrays(blob, len, &subject.points);
        if (arrays == NULL) {
            return 2;
        }
        subject.arrays = arrays;
    } else {
        int status = ecam_table_init(&table, blob, len);
        size_t bytes;

        if (status != ECAM_OK) {
            printf("error %d %s\n", status, ecam_status_name(status));
            return 1;
        }
        bytes = ecam_poly_bytes(&table);
        words = malloc(bytes + 8u);
        if (words == NULL) {
            return 2;
        }
        status = ecam_poly_init(&poly, &table, words, bytes);
        if (status != ECAM_OK) {
            printf("error %d %s\n", status, ecam_status_name(status));
            return 1;
        }
        if (strcmp(what, "runtime") == 0) {
            subject.table = &table;
        } else if (strcmp(what, "poly") == 0) {
            subject.poly = &poly;
        } else if (strcmp(what, "expanded") == 0) {
            subject.words = words;
        } else if (strcmp(what, "q16") == 0) {
            const size_t n = bytes / 8u;
            size_t k;

            q16 = malloc(n * sizeof *q16 + 4u);
            if (q16 == NULL) {
                return 2;
            }
            for (k = 0; k < n; k++) { /* whole counts (the fraction in Q16 carries the rest) */
                const int64_t v = asr64(words[k], blob[12]);
                q16[k] = v > INT32_MAX ? INT32_MAX : (v < INT32_MIN ? INT32_MIN : (int32_t)v);
            }
            subject.arrays = q16;
            subject.q16 = 1;
        } else {
            fprintf(stderr, "ecam_target: count runtime|minimal|poly|expanded|q16, not %s\n", what);
            return 2;
        }
    }
    for (i = 0; i < files && rc == 0; i++) {
        rc = count_file(query_paths[i], &subject);
    }
    free(arrays);
    free(q16);
    free(words);
    free(blob);
    return rc;
}

#if ECAM_TARGET_PAINT
#define PAINT_WORDS 1024u
#define PAINT_PATTERN 0xC0FFEE11u

/* Paints the PAINT_WORDS words below the current stack pointer, calls the lookup, and returns
 * how many bytes below the caller's stack pointer were written. Not inlined, so its own frame
 * sits above the painted area. */
static __attribute__((noinline)) unsigned painted_call(const ecam_table *t, int64_t m, int which)
{
    static ecam_table scratch;
    volatile uint32_t *sp;
    unsigned k;
    unsigned used = 0;
    int32_t p;
    int32_t s;

    __asm__ volatile("mov %0, sp" : "=r"(sp));
    for (k = 1; k <= PAINT_WORDS; k++) {
        sp[-(int)k] = PAINT_PATTERN;
    }
    if (which == 0) {
        p = ecam_table_position(t, m);
    } else if (which == 1) {
        p = ecam_table_slope(t, m);
    } else if (which == 3) {
        p = ecam_table_init(&scratch, t->position - ECAM_HEADER_BYTES,
                            (size_t)ECAM_HEADER_BYTES + (size_t)(t->intervals + 1u) * 4u *
                                (t->degree == 1u ? 1u : (t->degree == 3u ? 2u : 3u)));
    } else {
        ecam_table_lookup(t, m, &p, &s);
    }
    for (k = PAINT_WORDS; k >= 1; k--) {
        if (sp[-(int)k] != PAINT_PATTERN) {
            used = 4u * k;
            break;
        }
    }
    (void)p;
    return used;
}
#endif

static int do_stack(const char *blob_path, const char *query_path)
{
    run_input in;
    int rc = load(&in, blob_path, query_path);

    if (rc != 0) {
        return rc;
    }
#if ECAM_TARGET_PAINT
    {
        unsigned worst[4] = {0, 0, 0, 0};
        size_t k;
        int which;

        for (which = 0; which < 4; which++) {
            for (k = 0; k < in.count; k++) {
                const unsigned used = painted_call(&in.table, get_i64(in.query_bytes + 8u * k), which);
                if (used > worst[which]) {
                    worst[which] = used;
                }
            }
        }
        printf("position %u slope %u lookup %u init %u\n", worst[0], worst[1], worst[2], worst[3]);
    }
#else
    printf("unsupported\n");
#endif
    printf("table_bytes %u pair_bytes %u\n", (unsigned)sizeof(ecam_table), (unsigned)sizeof(ecam_table_pair));
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 5 && strcmp(argv[1], "lookup") == 0) {
        return do_lookup(argv[2], argv[3], argv[4]);
    }
    if (argc >= 3 && strcmp(argv[1], "status") == 0) {
        return do_status(argc - 2, argv + 2);
    }
    if (argc >= 5 && strcmp(argv[1], "count") == 0) {
        return do_count(argv[2], argv[3], argc - 4, argv + 4);
    }
    if (argc == 4 && strcmp(argv[1], "stack") == 0) {
        return do_stack(argv[2], argv[3]);
    }
    fprintf(stderr, "usage: ecam_target lookup BLOB QUERIES OUT | status BLOB... | "
                    "count BLOB runtime|minimal|poly|expanded|q16 QUERIES... | stack BLOB QUERIES\n");
    return 2;
}
