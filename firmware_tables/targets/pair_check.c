/*
 * pair_check.c - ecam_table_pair on a Cortex-M4 with a real interrupt (QEMU mps2-an386).
 *
 *   pair_check BLOB_A BLOB_B LOADS
 *
 * Reads two valid blobs (semihosting), computes the positions of 32 masters in each, then starts
 * SysTick: every tick the handler acquires the pair's active table and looks up all 32 masters,
 * which must match table A entirely or table B entirely. Meanwhile the main loop publishes A and
 * B alternately (retrying on ECAM_E_BUSY) and tries a corrupt blob between loads, which must be
 * rejected without disturbing the table in use. Prints
 * "ticks loads busy seen_a seen_b invalid mixed garbage"; exit 0 when mixed = garbage = 0.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ecam_table.h"

#define QUERIES 32u
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

static ecam_table_pair pair;
static int64_t masters[QUERIES];
static int32_t expected[2][QUERIES];
static volatile uint32_t ticks, seen_a, seen_b, seen_invalid, mixed, garbage;

void ecam_systick_handler(void);

/* The "control interrupt": one acquire, then lookups in that table only. */
void ecam_systick_handler(void)
{
    const ecam_table *t = ecam_pair_acquire(&pair);
    unsigned a = 0u, b = 0u, invalid = 0u, k;

    for (k = 0u; k < QUERIES; k++) {
        const int32_t p = ecam_table_position(t, masters[k]);
        if (p == expected[0][k] && p != expected[1][k]) {
            a++;
        } else if (p == expected[1][k] && p != expected[0][k]) {
            b++;
        } else if (p == ECAM_INVALID) {
            invalid++;
        } else if (p != expected[0][k]) {
            garbage++;
        }
    }
    if ((unsigned)(a > 0u) + (unsigned)(b > 0u) + (unsigned)(invalid > 0u) > 1u) {
        mixed++;
    }
    seen_a += (a > 0u) ? 1u : 0u;
    seen_b += (b > 0u) ? 1u : 0u;
    seen_invalid += (invalid > 0u) ? 1u : 0u;
    ticks++;
}

static unsigned char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    unsigned char *data = malloc(1u << 16);

    if (f == NULL || data == NULL) {
        exit(3);
    }
    *len = fread(data, 1, 1u << 16, f);
    fclose(f);
    return data;
}

int main(int argc, char **argv)
{
    size_t len_a, len_b, len_bad;
    unsigned char *blob_a, *blob_b, *bad;
    ecam_table ta, tb;
    unsigned long loads = 0, busy = 0, target, k;

    if (argc != 4) {
        return 2;
    }
    blob_a = slurp(argv[1], &len_a);
    blob_b = slurp(argv[2], &len_b);
    bad = slurp(argv[1], &len_bad);
    bad[len_bad - 1u] ^= 1u; /* payload CRC mismatch */
    target = strtoul(argv[3], NULL, 10);
    if (ecam_table_init(&ta, blob_a, len_a) != ECAM_OK || ecam_table_init(&tb, blob_b, len_b) != ECAM_OK) {
        return 4;
    }
    for (k = 0; k < QUERIES; k++) {
        masters[k] = (int64_t)k * 7919 - 100000;
        expected[0][k] = ecam_table_position(&ta, masters[k]);
        expected[1][k] = ecam_table_position(&tb, masters[k]);
    }
    ecam_pair_init(&pair);
    if (ecam_pair_load(&pair, blob_a, len_a) != ECAM_OK) {
        return 5;
    }
    SYST_RVR = 3000u; /* an interrupt every 3000 core clocks */
    SYST_CVR = 0u;
    SYST_CSR = 7u; /* enable, interrupt, core clock */
    while (loads < target) {
        const int rc = ecam_pair_load(&pair, (loads & 1u) ? blob_a : blob_b, (loads & 1u) ? len_a : len_b);
        if (rc == ECAM_OK) {
            loads++;
        } else if (rc == ECAM_E_BUSY) {
            busy++;
        } else {
            return 6;
        }
        if (ecam_pair_load(&pair, bad, len_bad) != ECAM_E_PAYLOAD_CRC) {
            return 7;
        }
    }
    SYST_CSR = 0u;
    printf("ticks %lu loads %lu busy %lu seen_a %lu seen_b %lu invalid %lu mixed %lu garbage %lu\n",
           (unsigned long)ticks, loads, busy, (unsigned long)seen_a, (unsigned long)seen_b,
           (unsigned long)seen_invalid, (unsigned long)mixed, (unsigned long)garbage);
    return (mixed == 0u && garbage == 0u && seen_invalid == 0u) ? 0 : 1;
}
