/*
 * ecam_minimal.c - the smallest fixed-point lookup of each degree, for measurement only.
 *
 * `ecam bench` (and tests/test_cross_targets.py) compile this file next to the runtime and count
 * the instructions of one call of each. It is what a hand-written lookup for ONE known table
 * costs, the yardstick of "within 2x of a minimal lookup":
 *
 *   - every format field is a compile-time constant (-DECAM_MIN_STEP=1024 -DECAM_MIN_TAU_BITS=10
 *     ...; the defaults are those of the shipped combination_drrd tables), so every shift is by a
 *     constant and the interval division by a constant becomes a shift or a multiply;
 *   - the arrays are aligned native int32 (no byte-wise little-endian reads);
 *   - the master is already inside [0, M): no wrap, no clamp, no checks; position only.
 *
 * The arithmetic is FORMAT.md steps 2..5 unchanged (the same Hermite coefficients, the same
 * flooring Horner and round-half-up), so for a master inside the period it returns the same bits
 * as ecam_table_position; the bench checks that on every query it counts.
 *
 * The coefficients are written the way that is cheapest on the core (exact integer identities of
 * step 4, so the same bits), as a hand-writer would, else the yardstick flatters the runtime:
 *   - 64-bit cores: scaled words, the quintic grouped as s = a0 + a1, u = b1 - b0 (x86-64 gcc
 *     -O2: 77 instructions for the golden quintic table, 90 ungrouped, the runtime 82);
 *   - 32-bit cores: each stored word times a constant w * 2^(W - Q), a 32x32 multiply-accumulate
 *     (Cortex-M4 -O2: 128 instead of 152 for that table, 61 instead of 63 for the cubic).
 * Never ship this: it trusts its inputs completely.
 *
 * Two more yardsticks with the coefficients of each interval's polynomial precomputed (issue 27):
 *   - ecam_minimal_expanded_<degree>: the expanded form's own lookup hand-written (the int64
 *     words of ecam_poly_init, FORMAT.md "Expanded form", with the format as constants): the same
 *     bits as ecam_poly_position inside the period;
 *   - ecam_minimal_q16_<degree>: the cheapest lookup a firmware engineer writes for a drive, one
 *     Horner chain of int32 multiply-shift-adds with the fraction in Q16 and int32 coefficients
 *     in whole counts (c_k / 2^W of step 4): fewer bits than the table (its results differ from
 *     the runtime's by up to a few counts), so it is the floor of the cost, not of the accuracy.
 */
#include <stddef.h>
#include <stdint.h>

#include "ecam_minimal.h"

#ifndef ECAM_MIN_STEP
#define ECAM_MIN_STEP 1024u /* h */
#endif
#ifndef ECAM_MIN_TAU_BITS
#define ECAM_MIN_TAU_BITS 10 /* F */
#endif
#ifndef ECAM_MIN_TAU_RECIP
#define ECAM_MIN_TAU_RECIP 4294967296u /* R = ceil(2^(32+F) / h) */
#endif
#ifndef ECAM_MIN_WORK_BITS
#define ECAM_MIN_WORK_BITS 38 /* W (linear: the position bits) */
#endif
#ifndef ECAM_MIN_POSITION_BITS
#define ECAM_MIN_POSITION_BITS 13 /* Qy */
#endif
#ifndef ECAM_MIN_SLOPE_BITS
#define ECAM_MIN_SLOPE_BITS 16 /* Qa */
#endif
#ifndef ECAM_MIN_CURVATURE_BITS
#define ECAM_MIN_CURVATURE_BITS 18 /* Qb */
#endif

#if defined(SIZE_MAX) && (SIZE_MAX > 0xFFFFFFFFu)
#define ECAM_MIN_WORD64 1
#else
#define ECAM_MIN_WORD64 0
#endif

#define ECAM_MIN_HALF (ECAM_MIN_WORK_BITS > 0 ? (INT64_C(1) << ECAM_MIN_WORK_BITS) >> 1 : 0)
#define ECAM_MIN_SCALE(bits) \
    (INT64_C(1) << ((bits) <= ECAM_MIN_WORK_BITS ? ECAM_MIN_WORK_BITS - (bits) : 0))
#define ECAM_MIN_SA ECAM_MIN_SCALE(ECAM_MIN_SLOPE_BITS)     /* 2^(W - Qa) */
#define ECAM_MIN_SB ECAM_MIN_SCALE(ECAM_MIN_CURVATURE_BITS) /* 2^(W - Qb) */

/* floor(x / 2^s), the spec's asr (one arithmetic shift instruction). */
static int64_t ecam_min_asr(int64_t x, int s)
{
    return x >= 0 ? x >> s : ~(~x >> s);
}

/* Step 2 and 3: interval and fraction (constant divisor and reciprocal). */
static uint32_t ecam_min_locate(uint32_t master, int64_t *tau)
{
    const uint32_t i = master / ECAM_MIN_STEP;
    const uint32_t offset = master - i * ECAM_MIN_STEP;

    if ((ECAM_MIN_STEP & (ECAM_MIN_STEP - 1u)) == 0u) {
        *tau = (int64_t)offset;
    } else {
        *tau = (int64_t)(((uint64_t)offset * (uint64_t)ECAM_MIN_TAU_RECIP) >> 32);
    }
    return i;
}

/* Step 5's last line. */
static int32_t ecam_min_out(int64_t y0, int64_t r, int64_t tau)
{
    const int64_t z = y0 * ECAM_MIN_SCALE(ECAM_MIN_POSITION_BITS) +
                      ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS) + ECAM_MIN_HALF;

    return (int32_t)ecam_min_asr(z, ECAM_MIN_WORK_BITS);
}

int32_t ecam_minimal_linear(const int32_t *position, uint32_t master)
{
    int64_t tau;
    const uint32_t i = ecam_min_locate(master, &tau);
    const int64_t y0 = position[i];
    const int64_t d = ((int64_t)position[i + 1u] - y0) * ECAM_MIN_SCALE(ECAM_MIN_POSITION_BITS);

    return ecam_min_out(y0, d, tau);
}

int32_t ecam_minimal_cubic(const int32_t *position, const int32_t *slope, uint32_t master)
{
    int64_t tau;
    const uint32_t i = ecam_min_locate(master, &tau);
    const int64_t y0 = position[i];
    const int64_t d = ((int64_t)position[i + 1u] - y0) * ECAM_MIN_SCALE(ECAM_MIN_POSITION_BITS);
#if ECAM_MIN_WORD64
    const int64_t a0 = (int64_t)slope[i] * ECAM_MIN_SA;
    const int64_t a1 = (int64_t)slope[i + 1u] * ECAM_MIN_SA;
    int64_t r = a0 + a1 - 2 * d;

    r = 3 * d - 2 * a0 - a1 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = a0 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
#else
    const int64_t a0 = slope[i];
    const int64_t a1 = slope[i + 1u];
    int64_t r = a0 * ECAM_MIN_SA + a1 * ECAM_MIN_SA - 2 * d;

    r = 3 * d + a0 * (-2 * ECAM_MIN_SA) + a1 * -ECAM_MIN_SA + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = a0 * ECAM_MIN_SA + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
#endif
    return ecam_min_out(y0, r, tau);
}

/* FORMAT.md step 4: c5 = 6d - 3a0 - 3a1 - b0 + b1, c4 = -15d + 8a0 + 7a1 + 3b0 - 2b1,
 * c3 = 10d - 6a0 - 4a1 - 3b0 + b1, c2 = b0, c1 = a0; on 64-bit cores with s = a0 + a1,
 * u = b1 - b0: c5 = 6d - 3s + u, c4 = 7s - 15d - 2u + a0 + b0, c3 = 10d - 4s + u - 2a0 - 2b0. */
int32_t ecam_minimal_quintic(const int32_t *position, const int32_t *slope,
                             const int32_t *curvature, uint32_t master)
{
    int64_t tau;
    const uint32_t i = ecam_min_locate(master, &tau);
    const int64_t y0 = position[i];
    const int64_t d = ((int64_t)position[i + 1u] - y0) * ECAM_MIN_SCALE(ECAM_MIN_POSITION_BITS);
#if ECAM_MIN_WORD64
    const int64_t a0 = (int64_t)slope[i] * ECAM_MIN_SA;
    const int64_t s = a0 + (int64_t)slope[i + 1u] * ECAM_MIN_SA;
    const int64_t b0 = (int64_t)curvature[i] * ECAM_MIN_SB;
    const int64_t u = (int64_t)curvature[i + 1u] * ECAM_MIN_SB - b0;
    int64_t r = 6 * d - 3 * s + u;

    r = 7 * s - 15 * d - 2 * u + a0 + b0 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = 10 * d - 4 * s + u - 2 * a0 - 2 * b0 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = b0 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = a0 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
#else
    const int64_t a0 = slope[i];
    const int64_t a1 = slope[i + 1u];
    const int64_t b0 = curvature[i];
    const int64_t b1 = curvature[i + 1u];
    int64_t r = 6 * d + a0 * (-3 * ECAM_MIN_SA) + a1 * (-3 * ECAM_MIN_SA) + b0 * -ECAM_MIN_SB +
                b1 * ECAM_MIN_SB;

    r = ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS) - 15 * d + a0 * (8 * ECAM_MIN_SA) +
        a1 * (7 * ECAM_MIN_SA) + b0 * (3 * ECAM_MIN_SB) + b1 * (-2 * ECAM_MIN_SB);
    r = ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS) + 10 * d + a0 * (-6 * ECAM_MIN_SA) +
        a1 * (-4 * ECAM_MIN_SA) + b0 * (-3 * ECAM_MIN_SB) + b1 * ECAM_MIN_SB;
    r = b0 * ECAM_MIN_SB + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = a0 * ECAM_MIN_SA + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
#endif
    return ecam_min_out(y0, r, tau);
}

/* Step 5 with the coefficients of step 4 precomputed as int64 words (ecam_poly_init's buffer:
 * c0 = Y0 2^(W-Qy) + half, then c1 .. cn). */
#define ECAM_MIN_MULSHIFT(r, tau) ecam_min_asr((r) * (tau), ECAM_MIN_TAU_BITS)

int32_t ecam_minimal_expanded_linear(const int64_t *c, uint32_t master)
{
    int64_t tau;
    const int64_t *k = &c[(size_t)ecam_min_locate(master, &tau) * 2u];

    return (int32_t)ecam_min_asr(k[0] + ECAM_MIN_MULSHIFT(k[1], tau), ECAM_MIN_WORK_BITS);
}

int32_t ecam_minimal_expanded_cubic(const int64_t *c, uint32_t master)
{
    int64_t tau;
    const int64_t *k = &c[(size_t)ecam_min_locate(master, &tau) * 4u];
    int64_t r = k[2] + ECAM_MIN_MULSHIFT(k[3], tau);

    r = k[1] + ECAM_MIN_MULSHIFT(r, tau);
    return (int32_t)ecam_min_asr(k[0] + ECAM_MIN_MULSHIFT(r, tau), ECAM_MIN_WORK_BITS);
}

int32_t ecam_minimal_expanded_quintic(const int64_t *c, uint32_t master)
{
    int64_t tau;
    const int64_t *k = &c[(size_t)ecam_min_locate(master, &tau) * 6u];
    int64_t r = k[4] + ECAM_MIN_MULSHIFT(k[5], tau);

    r = k[3] + ECAM_MIN_MULSHIFT(r, tau);
    r = k[2] + ECAM_MIN_MULSHIFT(r, tau);
    r = k[1] + ECAM_MIN_MULSHIFT(r, tau);
    return (int32_t)ecam_min_asr(k[0] + ECAM_MIN_MULSHIFT(r, tau), ECAM_MIN_WORK_BITS);
}

/* The interval and the fraction in Q16 (tau 2^16 / h), by constants. */
static uint32_t ecam_min_locate16(uint32_t master, int32_t *tau16)
{
    const uint32_t i = master / ECAM_MIN_STEP;
    const uint32_t offset = master - i * ECAM_MIN_STEP;

    if ((ECAM_MIN_STEP & (ECAM_MIN_STEP - 1u)) == 0u) {
        *tau16 = (int32_t)(ECAM_MIN_TAU_BITS <= 16 ? offset << (16 - ECAM_MIN_TAU_BITS % 17)
                                                    : offset >> (ECAM_MIN_TAU_BITS - 16) % 32);
    } else {
        *tau16 = (int32_t)(((uint64_t)offset * (uint64_t)((UINT64_C(1) << 48) / ECAM_MIN_STEP)) >> 32);
    }
    return i;
}

/* r = c_k + (r tau16 >> 16), in int32, the shift as one arithmetic shift. */
#define ECAM_MIN_Q16(c, r, tau16) ((c) + (int32_t)ecam_min_asr((int64_t)(r) * (tau16), 16))

int32_t ecam_minimal_q16_linear(const int32_t *c, uint32_t master)
{
    int32_t tau16;
    const int32_t *k = &c[(size_t)ecam_min_locate16(master, &tau16) * 2u];

    return ECAM_MIN_Q16(k[0], k[1], tau16);
}

int32_t ecam_minimal_q16_cubic(const int32_t *c, uint32_t master)
{
    int32_t tau16;
    const int32_t *k = &c[(size_t)ecam_min_locate16(master, &tau16) * 4u];
    int32_t r = ECAM_MIN_Q16(k[2], k[3], tau16);

    r = ECAM_MIN_Q16(k[1], r, tau16);
    return ECAM_MIN_Q16(k[0], r, tau16);
}

int32_t ecam_minimal_q16_quintic(const int32_t *c, uint32_t master)
{
    int32_t tau16;
    const int32_t *k = &c[(size_t)ecam_min_locate16(master, &tau16) * 6u];
    int32_t r = ECAM_MIN_Q16(k[4], k[5], tau16);

    r = ECAM_MIN_Q16(k[3], r, tau16);
    r = ECAM_MIN_Q16(k[2], r, tau16);
    r = ECAM_MIN_Q16(k[1], r, tau16);
    return ECAM_MIN_Q16(k[0], r, tau16);
}
