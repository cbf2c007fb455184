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
 * Never ship this: it trusts its inputs completely.
 */
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

#define ECAM_MIN_HALF (ECAM_MIN_WORK_BITS > 0 ? (INT64_C(1) << ECAM_MIN_WORK_BITS) >> 1 : 0)
#define ECAM_MIN_SCALE(bits) \
    (INT64_C(1) << ((bits) <= ECAM_MIN_WORK_BITS ? ECAM_MIN_WORK_BITS - (bits) : 0))

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
    const int64_t a0 = (int64_t)slope[i] * ECAM_MIN_SCALE(ECAM_MIN_SLOPE_BITS);
    const int64_t a1 = (int64_t)slope[i + 1u] * ECAM_MIN_SCALE(ECAM_MIN_SLOPE_BITS);
    int64_t r = a0 + a1 - 2 * d;

    r = 3 * d - 2 * a0 - a1 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = a0 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    return ecam_min_out(y0, r, tau);
}

int32_t ecam_minimal_quintic(const int32_t *position, const int32_t *slope,
                             const int32_t *curvature, uint32_t master)
{
    int64_t tau;
    const uint32_t i = ecam_min_locate(master, &tau);
    const int64_t y0 = position[i];
    const int64_t d = ((int64_t)position[i + 1u] - y0) * ECAM_MIN_SCALE(ECAM_MIN_POSITION_BITS);
    const int64_t a0 = (int64_t)slope[i] * ECAM_MIN_SCALE(ECAM_MIN_SLOPE_BITS);
    const int64_t a1 = (int64_t)slope[i + 1u] * ECAM_MIN_SCALE(ECAM_MIN_SLOPE_BITS);
    const int64_t b0 = (int64_t)curvature[i] * ECAM_MIN_SCALE(ECAM_MIN_CURVATURE_BITS);
    const int64_t b1 = (int64_t)curvature[i + 1u] * ECAM_MIN_SCALE(ECAM_MIN_CURVATURE_BITS);
    int64_t r = 6 * d - 3 * a0 - 3 * a1 - b0 + b1;

    r = 8 * a0 + 7 * a1 + 3 * b0 - 15 * d - 2 * b1 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = 10 * d - 6 * a0 - 4 * a1 - 3 * b0 + b1 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = b0 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    r = a0 + ecam_min_asr(r * tau, ECAM_MIN_TAU_BITS);
    return ecam_min_out(y0, r, tau);
}
