/*
 * switch_check.c - driver of ecam_table_pair.c (ecam_switch_pair) for the host and the cross
 * targets: files in, files out, little-endian whatever the target, so the host compares every
 * output with the Python SwitchPair (ecam/table_pair.py) bit for bit.
 *
 *   switch_check SCRIPT OUT BLOB...
 *
 * BLOB...: tables 0, 1, ... (ecam_table_init; a rejected blob stays a table that is not ready).
 * SCRIPT: commands of five int64 LE words (op, a, b, c, d):
 *   0 init                   ecam_switch_init
 *   1 engage  T MO SO        ecam_switch_engage(table T (-1: NULL), master offset, slave offset)
 *   2 arm     T MODE MO SO   ecam_switch_arm(table T (-1: NULL), mode, master offset, slave offset)
 *   3 cancel                 ecam_switch_cancel
 *   4 step    MASTER         ecam_switch_step
 * OUT: per command six int64 LE words: result, position, slope (ECAM_INVALID unless a step),
 * ecam_switch_boundary, ecam_switch_count, ecam_switch_pending.
 *
 *   switch_check count BLOB table|pair N STRIDE
 *
 * N samples at masters 0, STRIDE, 2 STRIDE, ... through ecam_table_lookup (table) or an engaged
 * pair's ecam_switch_step (pair), for an instruction counter (callgrind --toggle-collect=
 * ecam_table_lookup / ecam_switch_step); prints a checksum of the outputs.
 * Exit status 0, 2 on a usage, I/O or memory error. A test tool: it allocates, the runtime does
 * not.
 */
#include <stdio.h>
#include <stdlib.h>

#include "ecam_host_io.h"
#include "ecam_table_pair.h"

#define MAX_TABLES 16

static int64_t get_i64(const uint8_t *p)
{
    uint64_t u = 0u;
    int k;
    for (k = 7; k >= 0; k--) {
        u = (u << 8) | p[k];
    }
    return u <= (uint64_t)INT64_MAX ? (int64_t)u : -(int64_t)(~u) - 1;
}

static void put_i64(uint8_t *p, int64_t v)
{
    uint64_t u = (uint64_t)v;
    int k;
    for (k = 0; k < 8; k++) {
        p[k] = (uint8_t)(u & 0xFFu);
        u >>= 8;
    }
}

static int count_samples(char **argv)
{
    static ecam_table table;
    static ecam_switch_pair pair;
    size_t len;
    uint8_t *blob = ecam_host_read_file(argv[2], &len);
    const long n = atol(argv[4]), stride = atol(argv[5]);
    const int use_pair = argv[3][0] == 'p';
    int64_t sum = 0;
    long k;
    if (blob == NULL || ecam_table_init(&table, blob, len) != ECAM_OK ||
        ecam_switch_engage(&pair, &table, 0, 0) != ECAM_SWITCH_OK) {
        fprintf(stderr, "switch_check: cannot load %s\n", argv[2]);
        return 2;
    }
    for (k = 0; k < n; k++) {
        int32_t position, slope;
        const int64_t master = (int64_t)k * (int64_t)stride;
        if (use_pair) {
            (void)ecam_switch_step(&pair, master, &position, &slope);
        } else {
            ecam_table_lookup(&table, master, &position, &slope);
        }
        sum += (int64_t)position + slope;
    }
    printf("%lld\n", (long long)sum);
    free(blob);
    return 0;
}

int main(int argc, char **argv)
{
    static ecam_table tables[MAX_TABLES];
    static ecam_switch_pair pair;
    static uint8_t *blobs[MAX_TABLES];
    uint8_t *script, *out;
    size_t len, count, k;
    int n, i;
    FILE *f;

    if (argc == 6 && argv[1][0] == 'c' && argv[1][1] == 'o') {
        return count_samples(argv);
    }
    if (argc < 3 || argc - 3 > MAX_TABLES) {
        fprintf(stderr, "usage: switch_check SCRIPT OUT BLOB... (at most %d)\n", MAX_TABLES);
        return 2;
    }
    n = argc - 3;
    for (i = 0; i < n; i++) {
        size_t blob_len;
        uint8_t *blob = ecam_host_read_file(argv[3 + i], &blob_len);
        if (blob == NULL) {
            fprintf(stderr, "switch_check: cannot read %s\n", argv[3 + i]);
            return 2;
        }
        blobs[i] = blob; /* kept until the end: the tables refer to it */
        (void)ecam_table_init(&tables[i], blob, blob_len);
    }
    script = ecam_host_read_file(argv[1], &len);
    if (script == NULL || len % 40u != 0u) {
        fprintf(stderr, "switch_check: cannot read %s as 40-byte commands\n", argv[1]);
        return 2;
    }
    count = len / 40u;
    out = malloc(count * 48u + 1u);
    if (out == NULL) {
        return 2;
    }
    ecam_switch_init(&pair);
    for (k = 0; k < count; k++) {
        const uint8_t *command = script + 40u * k;
        const int64_t op = get_i64(command), a = get_i64(command + 8u), b = get_i64(command + 16u);
        const int64_t c = get_i64(command + 24u), d = get_i64(command + 32u);
        const ecam_table *t = (a >= 0 && a < n) ? &tables[a] : NULL;
        int32_t position = ECAM_INVALID, slope = ECAM_INVALID;
        int rc = 0;
        switch (op) {
        case 0:
            ecam_switch_init(&pair);
            break;
        case 1:
            rc = ecam_switch_engage(&pair, t, b, (int32_t)c);
            break;
        case 2:
            rc = ecam_switch_arm(&pair, t, (unsigned)b, c, (int32_t)d);
            break;
        case 3:
            rc = ecam_switch_cancel(&pair);
            break;
        case 4:
            rc = ecam_switch_step(&pair, a, &position, &slope);
            break;
        default:
            fprintf(stderr, "switch_check: unknown command %lld\n", (long long)op);
            return 2;
        }
        put_i64(out + 48u * k, rc);
        put_i64(out + 48u * k + 8u, position);
        put_i64(out + 48u * k + 16u, slope);
        put_i64(out + 48u * k + 24u, ecam_switch_boundary(&pair));
        put_i64(out + 48u * k + 32u, (int64_t)ecam_switch_count(&pair));
        put_i64(out + 48u * k + 40u, ecam_switch_pending(&pair));
    }
    f = fopen(argv[2], "wb");
    if (f == NULL || fwrite(out, 1, count * 48u, f) != count * 48u || fclose(f) != 0) {
        fprintf(stderr, "switch_check: cannot write %s\n", argv[2]);
        return 2;
    }
    free(out);
    free(script);
    for (i = 0; i < n; i++) {
        free(blobs[i]);
    }
    return 0;
}
