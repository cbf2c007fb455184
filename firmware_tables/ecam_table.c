/*
 * ecam_table.c - C99 reference runtime for ecam cam tables, format versions 1 and 2 (FORMAT.md).
 *
 * Arithmetic convention: FORMAT.md specifies signed 64-bit intermediates. This file carries them
 * as uint64_t two's-complement bit patterns: addition, subtraction and multiplication are then
 * exactly the signed results mod 2^64, no operation has undefined behaviour, and the arithmetic
 * shifts read the sign bit themselves. The loader proves, for every table it accepts, that no
 * intermediate of the lookup leaves int64 and that both outputs fit int32 (FORMAT.md, "Overflow
 * proof"), so the results are the spec's bit for bit, the same as the Python lookup.
 *
 * Speed: ecam_table_init precomputes the format (shift counts, scale factors, reciprocals, the
 * clamped end positions) and picks one kernel per degree and step kind; a master inside the
 * period skips the wrap; the wrap itself is a divide-free Barrett reduction (the expanded form's
 * for h = 2^k, on cores that divide in one instruction, two 32-bit remainders). Two arithmetic
 * paths give the same bits: on 64-bit cores a product and an arithmetic shift; on 32-bit cores
 * (ECAM_WORD_BITS 32) asr(x * tau, F) becomes the high word of x * (tau * 2^(32-F)), so every
 * Horner step is two 32x32 multiplies and no variable 64-bit shift.
 */
#include <stdbool.h>

#include "ecam_table.h"

#ifndef ECAM_WORD_BITS
#if defined(SIZE_MAX) && (SIZE_MAX > 0xFFFFFFFFu)
#define ECAM_WORD_BITS 64
#else
#define ECAM_WORD_BITS 32
#endif
#endif

#ifndef ECAM_MEMORY_BARRIER
#define ECAM_MEMORY_BARRIER() ((void)0)
#endif

/* 1 when the core divides 32-bit integers in one instruction (ACLE's __ARM_FEATURE_IDIV: the
 * Cortex-M3, M4, M7 UDIV/SDIV), which the expanded form's wrap of a table with h = 2^k then uses
 * on 32-bit cores (ecam_poly_fold); 0 (the Cortex-M0, where `/` is a library call, and 64-bit
 * cores, whose Barrett quotient is one multiply) keeps the divide-free wrap. Define it to 1 to
 * run that path on another 32-bit build (the tests do, on the host). */
#ifndef ECAM_HW_DIVIDE
#if defined(__ARM_FEATURE_IDIV) && (__ARM_FEATURE_IDIV == 1)
#define ECAM_HW_DIVIDE 1
#else
#define ECAM_HW_DIVIDE 0
#endif
#endif
#define ECAM_POLY_FOLD ((ECAM_WORD_BITS != 64) && (ECAM_HW_DIVIDE != 0))

/* Inlining hints only: the code is correct and C99 without them (FORMAT.md, deviations). */
#if defined(__GNUC__)
#define ECAM_INLINE __inline__ __attribute__((always_inline))
#define ECAM_COLD __attribute__((noinline))
#else
#define ECAM_INLINE inline
#define ECAM_COLD
#endif

/* GCC only: no instruction scheduling before register allocation in the functions marked, which
 * on the Cortex-M4 at -O2 stretches the live ranges of the quintic's 64-bit values into spills
 * (gcc 12: ecam_lookup_at_quintic's frame 72 B with it, 56 B without; the budget is 64 B per
 * call, FORMAT.md). A hint only: the code is the same C99 without it. */
#if defined(__GNUC__) && !defined(__clang__)
#define ECAM_LEAN __attribute__((optimize("no-schedule-insns")))
#else
#define ECAM_LEAN
#endif

/* Byte offsets of the header fields, from the table in FORMAT.md. */
#define ECAM_OFF_VERSION 4u
#define ECAM_OFF_HEADER_BYTES 6u
#define ECAM_OFF_DEGREE 8u
#define ECAM_OFF_FLAGS 9u
#define ECAM_OFF_STEP_SHIFT 10u
#define ECAM_OFF_TAU_BITS 11u
#define ECAM_OFF_WORK_BITS 12u
#define ECAM_OFF_SLOPE_BITS 13u
#define ECAM_OFF_CURVATURE_BITS 14u
#define ECAM_OFF_SLOPE_PRESHIFT 15u
#define ECAM_OFF_POINTS 16u
#define ECAM_OFF_MASTER_COUNTS 20u
#define ECAM_OFF_STEP_COUNTS 24u
#define ECAM_OFF_POSITION_BITS 28u
#define ECAM_OFF_RESERVED_A 29u
#define ECAM_OFF_TAU_RECIP 32u
#define ECAM_OFF_PAYLOAD_BYTES 40u
#define ECAM_OFF_PAYLOAD_CRC 44u
#define ECAM_OFF_RESERVED_B 48u
#define ECAM_OFF_HEADER_CRC 60u

/* ecam_table.periodic: what a master outside [0, M) does. */
#define ECAM_CLAMP 0u    /* not periodic: hold the end position, slope 0 */
#define ECAM_WRAP 1u     /* periodic: m mod M */
#define ECAM_WRAP_NET 2u /* periodic with a net stroke: m mod M, plus step 7 */

/* Field limits, from the rules column of FORMAT.md. */
#define ECAM_MAX_TAU_BITS 30u
#define ECAM_MAX_WORK_BITS 40u
#define ECAM_MAX_POSITION_BITS 30u
#define ECAM_MAX_SHIFT 63u
#define ECAM_SLOPE_FRACTION_BITS 16u
#define ECAM_MIN_MASTER_COUNTS 2u
#define ECAM_MAX_MASTER_COUNTS (UINT32_C(1) << 31)
#define ECAM_MAX_STEP_COUNTS (UINT32_C(1) << 30)
#define ECAM_SIGN_BIT64 (UINT64_C(1) << 63)
#define ECAM_SIGN_BIT32 ((uint32_t)0x80000000u)
#define ECAM_INT32_LIMIT ((uint32_t)0x7FFFFFFFu)
#define ECAM_NET_SMALL_DEN 65536u /* D up to 2^16: step 7's last quotient fits 32 bits */
#define ECAM_MAX_RAMP 32767u      /* |S| of version 3: S 2^16 fits the int32 slope */

/* ------------------------------------------------------------------------------------------ */
/* Byte access and integer helpers                                                            */
/* ------------------------------------------------------------------------------------------ */

/* Little-endian u16 read that works at any alignment and on any host byte order. */
static uint32_t ecam_get_u16(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8);
}

/* Little-endian u32 read at any alignment and byte order (compilers merge it into one load). */
static ECAM_INLINE uint32_t ecam_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

/* Little-endian u64 read (tau_recip) that works at any alignment and byte order. */
static uint64_t ecam_get_u64(const uint8_t *p)
{
    return (uint64_t)ecam_get_u32(p) | ((uint64_t)ecam_get_u32(&p[4]) << 32);
}

/* Bits of a stored int32 to its value, portably (a plain cast is implementation-defined). */
static ECAM_INLINE int32_t ecam_i32(uint32_t u)
{
    if (u <= ECAM_INT32_LIMIT) {
        return (int32_t)u;
    }
    const uint32_t offset = u - ECAM_SIGN_BIT32; /* 0 .. 2^31 - 1 */

    return (int32_t)offset - INT32_MAX - 1;
}

/* Bits of a 64-bit word to its signed value, portably. */
static ECAM_INLINE int64_t ecam_i64(uint64_t u)
{
    if (u <= (uint64_t)INT64_MAX) {
        return (int64_t)u;
    }
    const uint64_t magnitude = ~u; /* |value| - 1, below 2^63 */

    return -(int64_t)magnitude - 1;
}

/* Sign-extends the bits of a stored int32 into the uint64 two's-complement working word. */
static ECAM_INLINE uint64_t ecam_sext32(uint32_t u)
{
    return (uint64_t)(int64_t)ecam_i32(u);
}

/* FORMAT.md asr(x, s) = floor(x / 2^s) for s <= 63: the spec's x >= 0 ? x >> s : ~(~x >> s),
 * which compilers turn into one arithmetic shift instruction. */
static ECAM_INLINE uint64_t ecam_asr(uint64_t x, unsigned s)
{
    const int64_t v = ecam_i64(x);

    return (uint64_t)(v >= 0 ? v >> s : ~(~v >> s));
}

/* asr(x, s) for any s: counts past 63 give the exact floor, 0 or -1 (a C shift would be UB). */
static ECAM_INLINE uint64_t ecam_asr_any(uint64_t x, unsigned s)
{
    if (s > ECAM_MAX_SHIFT) {
        return (x & ECAM_SIGN_BIT64) != 0u ? UINT64_MAX : 0u;
    }
    return ecam_asr(x, s);
}

#if ECAM_WORD_BITS != 64
/* 32-bit asr, the same idiom on int32 (the 32-bit cores' final shift). */
static ECAM_INLINE uint32_t ecam_asr32(uint32_t x, unsigned s)
{
    const int32_t v = ecam_i32(x);

    return (uint32_t)(v >= 0 ? v >> s : ~(~v >> s));
}
#endif

/* Full 64x64 -> 128-bit product from 32-bit limbs (the loader's checks). */
static void ecam_mul_64x64(uint64_t a, uint64_t b, uint64_t *hi, uint64_t *lo)
{
    const uint64_t mask = (uint64_t)0xFFFFFFFFu;
    const uint64_t p0 = (a & mask) * (b & mask);
    const uint64_t p1 = (a & mask) * (b >> 32);
    const uint64_t p2 = (a >> 32) * (b & mask);
    const uint64_t p3 = (a >> 32) * (b >> 32);
    /* Three terms below 2^32 each: mid < 3 * 2^32, no overflow. */
    const uint64_t mid = (p0 >> 32) + (p1 & mask) + (p2 & mask);

    *lo = (mid << 32) | (p0 & mask);
    *hi = p3 + (p1 >> 32) + (p2 >> 32) + (mid >> 32);
}

#if ECAM_WORD_BITS == 64 && defined(__SIZEOF_INT128__) && !defined(ECAM_NO_INT128)
/* A compiler extension (GCC, Clang): one multiply instruction for a Barrett quotient. */
__extension__ typedef __int128 ecam_int128;
__extension__ typedef unsigned __int128 ecam_uint128;
#define ECAM_HAVE_INT128 1
#else
#define ECAM_HAVE_INT128 0
#endif

/* High 64 bits of u * mu (a Barrett quotient): one multiply with __int128, else from 32-bit
 * limbs, where each partial sum is a * b + c (+ d) with 32-bit a, b, c, d, which never exceeds
 * 2^64 - 1. The lookups' own helper: the loader's ecam_mul_64x64 is not shared with them. */
static ECAM_INLINE uint64_t ecam_mulhi_64x64(uint64_t u, uint64_t mu)
{
#if ECAM_HAVE_INT128
    return (uint64_t)(((ecam_uint128)u * mu) >> 64);
#else
    const uint32_t u0 = (uint32_t)u;
    const uint32_t u1 = (uint32_t)(u >> 32);
    const uint32_t m0 = (uint32_t)mu;
    const uint32_t m1 = (uint32_t)(mu >> 32);
    const uint64_t p00 = (uint64_t)u0 * m0;
    const uint64_t p01 = (uint64_t)u0 * m1 + (uint32_t)(p00 >> 32);
    const uint64_t p10 = (uint64_t)u1 * m0 + (uint32_t)p01;

    return (uint64_t)u1 * m1 + (uint32_t)(p01 >> 32) + (uint32_t)(p10 >> 32);
#endif
}

/* ------------------------------------------------------------------------------------------ */
/* CRC-32                                                                                     */
/* ------------------------------------------------------------------------------------------ */

/* Nibble table of the reflected IEEE polynomial 0xEDB88320: 64 bytes of flash instead of 1 KiB. */

/* Same value as zlib.crc32, so blobs written by Python tools verify here. */
uint32_t ecam_crc32(const uint8_t *data, size_t len)
{
    static const uint32_t ecam_crc_nibble[16] = {
        0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu, 0x76DC4190u, 0x6B6B51F4u,
        0x4DB26158u, 0x5005713Cu, 0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu,
        0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu};

    uint32_t crc = 0xFFFFFFFFu;
    size_t n;

    for (n = 0; n < len; n++) {
        crc ^= data[n];
        crc = (crc >> 4) ^ ecam_crc_nibble[crc & 0x0Fu];
        crc = (crc >> 4) ^ ecam_crc_nibble[crc & 0x0Fu];
    }
    return crc ^ 0xFFFFFFFFu;
}

/* ------------------------------------------------------------------------------------------ */
/* Lookup kernels (FORMAT.md "Lookup")                                                        */
/* ------------------------------------------------------------------------------------------ */

#if ECAM_HAVE_INT128
/*
 * Step 1 for a periodic table and a master outside [0, M): m mod M (floor modulo) for every int64
 * m, without a divide. Signed Barrett reduction with mu = floor((2^64 - 1) / M) < 2^63: with
 * mu = 2^64 / M - e, 0 < e < 1 + 1/M, q = floor(m * mu / 2^64) = floor(m / M - m e / 2^64) and
 * |m e / 2^64| < 3/4, so q is floor(m / M) - 1 or floor(m / M) for m >= 0, floor(m / M) or
 * floor(m / M) + 1 for m < 0: r = m - q M lies in [-M, 2M) (|r| < 2^32, computed mod 2^64 as its
 * bits; q M alone may leave int64 near INT64_MIN), and one correction lands it in [0, M).
 */
static ECAM_INLINE uint32_t ecam_wrap(const ecam_table *t, int64_t m)
{
    const ecam_int128 product = (ecam_int128)m * (ecam_int128)(int64_t)t->mod_recip; /* mu < 2^63 */
    const int64_t q = (int64_t)(product >= 0 ? product >> 64 : ~(~product >> 64));
    const int64_t r = ecam_i64((uint64_t)m - (uint64_t)q * t->master_counts);

    /* r + M (r < 0) and r - M (r >= M) lie in [0, M): their low words are the sums mod 2^32 */
    if (r < 0) {
        return (uint32_t)r + t->master_counts;
    }
    if (r >= (int64_t)t->master_counts) {
        return (uint32_t)r - t->master_counts;
    }
    return (uint32_t)r;
}
#else
/*
 * Step 1 for a periodic table and a master outside [0, M): m mod M (floor modulo) for every int64
 * m, INT64_MIN included, without a divide. Flipping the sign bit maps m to u = m + 2^63 in
 * [0, 2^64), and m mod M = (u mod M - 2^63 mod M) mod M (one conditional add or subtract).
 * u mod M by Barrett reduction with mu = floor((2^64 - 1) / M), 2 <= M <= 2^31: q = hi(u * mu)
 * satisfies floor(u / M) - 1 <= q <= floor(u / M) (mu <= 2^64 / M and mu > 2^64 / M - 1), so
 * r = u - q * M lies in [0, 2M), below 2^32: it is computed exactly in 32 bits, and one
 * conditional subtraction lands it in [0, M). Out of line: the kernels' fast path stays small.
 */
static ECAM_INLINE uint32_t ecam_wrap(const ecam_table *t, int64_t m)
{
    const uint64_t u = (uint64_t)m ^ ECAM_SIGN_BIT64;
    const uint64_t q = ecam_mulhi_64x64(u, t->mod_recip);
    uint32_t r = (uint32_t)u - (uint32_t)q * t->master_counts;

    if (r >= t->master_counts) {
        r -= t->master_counts;
    }
    if (r >= t->mod_offset) {
        return r - t->mod_offset;
    }
    return r + t->mod_complement;
}
#endif

/* Steps 2 and 3: interval index i and fraction tau. For h = 2^k a shift and a mask (tau = t).
 * Otherwise g = floor(2^32 / h) (h >= 3) and i' = floor(m * g / 2^32) needs at most one
 * correction: g <= 2^32 / h gives i' <= i, and g > 2^32 / h - 1 gives i' > m / h - m / 2^32 >
 * i - 1 (m < 2^31). Then tau = floor(t * R / 2^32) (t * R < 2^63). */
static ECAM_INLINE uint32_t ecam_locate(const ecam_table *t, uint32_t local, bool pow2,
                                        uint32_t *tau)
{
    uint32_t i;
    uint32_t rest;

    if (pow2) {
        *tau = local & t->step_mask;
        return local >> t->step_shift;
    }
    i = (uint32_t)(((uint64_t)local * t->step_recip) >> 32);
    rest = local - i * t->step_counts;
    if (rest >= t->step_counts) {
        rest -= t->step_counts;
        i++;
    }
    *tau = (uint32_t)(((uint64_t)rest * t->tau_recip) >> 32);
    return i;
}

/* The int32 result of asr(z, S) (S = out_shift, 0..63), which the proof keeps inside int32. */
static ECAM_INLINE int32_t ecam_out(const ecam_table *t, uint64_t z)
{
#if ECAM_WORD_BITS == 64
    return ecam_i32((uint32_t)ecam_asr(z, t->out_shift));
#else
    /* No 64-bit shift: with y = out_mul and e = out_rshift, low32(floor(z / 2^S)) =
     * asr32(low32(floor(z * y / 2^32)), e), and floor(z * y / 2^32) = z_high * y +
     * floor(z_low * y / 2^32) exactly (z_high signed). S <= 32: y = 2^(32-S), e = 0 (the result
     * fits int32, so its low word is it); S > 32: y = 1, e = S - 32. y = 2^32 (S = 0) has a high
     * word, y_h, which adds z_low * y_h. */
    const uint32_t low = (uint32_t)z;
    const uint32_t high = (uint32_t)(z >> 32);
    const uint32_t y_low = (uint32_t)t->out_mul;
    const uint32_t y_high = (uint32_t)(t->out_mul >> 32);
    const uint32_t scaled =
        (uint32_t)(((uint64_t)low * y_low) >> 32) + (high * y_low) + (low * y_high);

    return ecam_i32(ecam_asr32(scaled, t->out_rshift));
#endif
}

/* Step 6: slope = asr(asr(q, P) * R, 16 + F + W - P), the Q16 slope per master count.
 * P may reach 86; ecam_asr_any gives the exact floor for counts past 63. */
static ECAM_INLINE int32_t ecam_slope_out(const ecam_table *t, uint64_t q)
{
    return ecam_i32(
        (uint32_t)ecam_asr(ecam_asr_any(q, t->slope_preshift) * t->tau_recip, t->slope_out_shift));
}

/* Steps 4 and 5 of a linear table. W = Qy, so D = Y1 - Y0 and, by floor(floor(x/a)/b) =
 * floor(x/(ab)) for integers, asr(Y0 + asr(D tau, F) + half, W)
 *   = asr(Y0 (2^F - tau) + Y1 tau + half 2^F, F + W),
 * two 32x32 multiply-accumulates; every term is below 2^61, so nothing overflows. */
static ECAM_INLINE int32_t ecam_linear_at(const ecam_table *t, uint32_t i, uint32_t tau)
{
    const uint8_t *p = &t->position[(size_t)i * 4u];
    const int64_t y0 = ecam_i32(ecam_get_u32(p));
    const int64_t y1 = ecam_i32(ecam_get_u32(&p[4]));
    const uint32_t rest = t->tau_one - tau; /* 2^F - tau, at most 2^30 */
#if ECAM_WORD_BITS == 64
    const int64_t z = y0 * (int64_t)rest + y1 * (int64_t)tau;
#else
    /* Both factors are at most 2^30: two 32x32 signed multiply-accumulates. */
    const int64_t z = (y0 * (int32_t)rest) + (y1 * (int32_t)tau);
#endif

    return ecam_out(t, (uint64_t)z + t->round);
}

#if ECAM_WORD_BITS == 64

/* The fraction as the Horner steps take it: tau itself. */
typedef uint64_t ecam_horner_fraction;

static ECAM_INLINE uint64_t ecam_horner_tau(const ecam_table *t, uint32_t tau)
{
    (void)t;
    return tau;
}

/* asr(x * tau, F): one multiply, one arithmetic shift. */
static ECAM_INLINE uint64_t ecam_mulshift(const ecam_table *t, uint64_t x, uint64_t tau)
{
    return ecam_asr(x * tau, t->tau_bits);
}

#else

/* The fraction as the Horner steps take it: tau * 2^(32 - F), below 2^32 (F = 0: tau = 0). */
typedef uint32_t ecam_horner_fraction;

static ECAM_INLINE uint32_t ecam_horner_tau(const ecam_table *t, uint32_t tau)
{
    return tau << t->tau_lshift;
}

/* asr(x * tau, F) = floor(x * (tau 2^(32-F)) / 2^32): the high part of a 64x32 product, two
 * 32x32 multiplies and no variable 64-bit shift. For a negative x (bits xu = x + 2^64),
 * floor(x * y / 2^32) = floor(xu * y / 2^32) - y * 2^32. */
static ECAM_INLINE uint64_t ecam_mulshift(const ecam_table *t, uint64_t x, uint32_t y)
{
    const uint64_t low = (uint64_t)(uint32_t)x * y;
    const uint32_t x_high = (uint32_t)(x >> 32);
    const uint64_t high = (uint64_t)x_high * y + (low >> 32);

    (void)t;
    const uint32_t correction = y & (0u - (x_high >> 31)); /* y when x < 0, else 0 */

    return high - ((uint64_t)correction << 32);
}

#endif

/* A stored value times a scale 2^(W - Q) of any size (up to 2^40). */
static uint64_t ecam_scaled_any(const uint8_t *p, uint64_t scale)
{
    return (uint64_t)(int64_t)ecam_i32(ecam_get_u32(p)) * scale;
}

#if ECAM_WORD_BITS == 64

/* A stored value times its scale 2^(W - Q): one multiply. */
static ECAM_INLINE uint64_t ecam_scaled(const uint8_t *p, uint64_t scale)
{
    return (uint64_t)(int64_t)ecam_i32(ecam_get_u32(p)) * scale;
}

#else

/* A stored value times its scale 2^(W - Q) <= 2^30 (the fast kernels' condition on 32-bit
 * cores): one 32x32 signed multiply. */
static ECAM_INLINE uint64_t ecam_scaled(const uint8_t *p, uint64_t scale)
{
    const uint32_t scale_bits = (uint32_t)scale;
    const int64_t product = (int64_t)ecam_i32(ecam_get_u32(p)) * (int32_t)scale_bits;

    return (uint64_t)product;
}

/* acc + word * multiplier (w * 2^(W - Q), which init checked fits int32): one 32x32 signed
 * multiply-accumulate. */
static ECAM_INLINE uint64_t ecam_mac(uint64_t acc, int32_t word, int32_t multiplier)
{
    const int64_t product = (int64_t)word * multiplier;

    return acc + (uint64_t)product;
}

#endif


/* Steps 4 and 5 (position) or 4 and 6 (slope, before its final shifts) of a cubic table:
 * c3 = a0 + a1 - 2D, c2 = 3D - 2a0 - a1, c1 = a0 (FORMAT.md step 4), then Horner with flooring
 * inner shifts; the slope's Horner is the derivative's: q = 3 c3, 2 c2 + .., c1 + ... */
#if ECAM_WORD_BITS == 64
static ECAM_INLINE int32_t ecam_cubic_at(const ecam_table *t, uint32_t i, uint32_t tau_in, bool slope,
                                         bool lean)
{
    const size_t at = (size_t)i * 4u;
    const ecam_horner_fraction tau = ecam_horner_tau(t, tau_in);
    const uint64_t y0 = ecam_scaled(&t->position[at], t->position_scale);
    const uint64_t d = ecam_scaled(&t->position[at + 4u], t->position_scale) - y0;
    const uint64_t a0 = ecam_scaled(&t->slope[at], t->slope_scale);
    const uint64_t a1 = ecam_scaled(&t->slope[at + 4u], t->slope_scale);
    uint64_t r;

    (void)lean; /* 64-bit cores have one position path */

    if (slope) {
        r = 6u * d - 4u * a0 - 2u * a1 + ecam_mulshift(t, 3u * (a0 + a1 - 2u * d), tau);
        return ecam_slope_out(t, a0 + ecam_mulshift(t, r, tau));
    }
    r = a0 + a1 - 2u * d;
    r = 3u * d - 2u * a0 - a1 + ecam_mulshift(t, r, tau);
    r = a0 + ecam_mulshift(t, r, tau);
    return ecam_out(t, y0 + ecam_mulshift(t, r, tau) + t->round);
}
#else
/* On 32-bit cores the stored position Y0 stays a 32-bit word until the last step and
 * D = (Y1 - Y0) * 2^(W - Qy) is formed from the 64-bit difference: a 32x32 multiply, or a
 * 64-bit one for a scale past 2^30 (fine tables). */
static ECAM_INLINE int32_t ecam_cubic_at(const ecam_table *t, uint32_t i, uint32_t tau_in, bool slope,
                                         bool lean)
{
    const size_t at = (size_t)i * 4u;
    const ecam_horner_fraction tau = ecam_horner_tau(t, tau_in);
    const int32_t y0 = ecam_i32(ecam_get_u32(&t->position[at]));
    const uint64_t dy = (uint64_t)(int64_t)ecam_i32(ecam_get_u32(&t->position[at + 4u])) -
                        (uint64_t)(int64_t)y0;
    const uint64_t d = (lean || (t->position_wide != 0u)) ? (dy * t->position_scale)
                                                 : (dy * (uint32_t)t->position_scale);
    const uint64_t a0 = ecam_scaled(&t->slope[at], t->slope_scale);
    const uint64_t a1 = ecam_scaled(&t->slope[at + 4u], t->slope_scale);
    uint64_t r;

    if (slope) {
        r = 6u * d - 4u * a0 - 2u * a1 + ecam_mulshift(t, 3u * (a0 + a1 - 2u * d), tau);
        return ecam_slope_out(t, a0 + ecam_mulshift(t, r, tau));
    }
    r = a0 + a1 - 2u * d;
    r = 3u * d - 2u * a0 - a1 + ecam_mulshift(t, r, tau);
    r = a0 + ecam_mulshift(t, r, tau);
    r = ecam_mulshift(t, r, tau) + t->round;
    if (lean || (t->position_wide != 0u)) {
        return ecam_out(t, r + ((uint64_t)(int64_t)y0 * t->position_scale));
    }
    return ecam_out(t, ecam_mac(r, y0, (int32_t)(uint32_t)t->position_scale));
}
#endif

#if ECAM_WORD_BITS == 64

/* Steps 4 and 5 (or 4 and 6) of a quintic table on 64-bit cores: the coefficients of FORMAT.md
 * step 4 with s = a0 + a1 and u = b1 - b0: c5 = 6d - 3s + u, c4 = 7s - 15d - 2u + a0 + b0,
 * c3 = 10d - 4s + u - 2a0 - 2b0, c2 = b0, c1 = a0. */
static ECAM_INLINE int32_t ecam_quintic_at(const ecam_table *t, uint32_t i, uint32_t tau_in,
                                           bool slope, bool lean)
{
    const size_t at = (size_t)i * 4u;
    const ecam_horner_fraction tau = ecam_horner_tau(t, tau_in);
    const uint64_t y0 = ecam_scaled(&t->position[at], t->position_scale);
    const uint64_t d = ecam_scaled(&t->position[at + 4u], t->position_scale) - y0;
    const uint64_t a0 = ecam_scaled(&t->slope[at], t->slope_scale);
    const uint64_t s = a0 + ecam_scaled(&t->slope[at + 4u], t->slope_scale);
    const uint64_t b0 = ecam_scaled(&t->curvature[at], t->curvature_scale);
    const uint64_t u = ecam_scaled(&t->curvature[at + 4u], t->curvature_scale) - b0;
    const uint64_t k = slope ? UINT64_C(1) : UINT64_C(0);

    (void)lean; /* 64-bit cores have one position path */
    uint64_t r = (1u + 4u * k) * (6u * d - 3u * s + u);

    r = (1u + 3u * k) * (7u * s - 15u * d - 2u * u + a0 + b0) + ecam_mulshift(t, r, tau);
    r = (1u + 2u * k) * (10u * d - 4u * s + u - 2u * a0 - 2u * b0) + ecam_mulshift(t, r, tau);
    r = (1u + k) * b0 + ecam_mulshift(t, r, tau);
    r = a0 + ecam_mulshift(t, r, tau);
    if (slope) {
        return ecam_slope_out(t, r);
    }
    return ecam_out(t, y0 + ecam_mulshift(t, r, tau) + t->round);
}

#else

/* Steps 4 and 5 (or 4 and 6) of a quintic table on 32-bit cores. FORMAT.md step 4's
 * coefficients as c5 = 6D + (-3 a0 - 3 a1 - b0 + b1), c4 = -15D + (8 a0 + 7 a1 + 3 b0 - 2 b1),
 * c3 = 10D + (-6 a0 - 4 a1 - 3 b0 + b1), c2 = b0, c1 = a0: the slope and curvature words stay
 * 32-bit and each bracket is a chain of four multiply-accumulates onto the previous Horner
 * product (multipliers from init), so few 64-bit values are live and the frame stays small. */
static ECAM_INLINE int32_t ecam_quintic_at(const ecam_table *t, uint32_t i, uint32_t tau_in,
                                           bool slope, bool lean)
{
    const size_t at = (size_t)i * 4u;
    const ecam_horner_fraction tau = ecam_horner_tau(t, tau_in);
    const int32_t y0 = ecam_i32(ecam_get_u32(&t->position[at]));
    /* D = (Y1 - Y0) * 2^(W - Qy) with Y1 - Y0 as a 64-bit value: no 64-bit Y0 stays live. */
    const uint64_t dy = (uint64_t)(int64_t)ecam_i32(ecam_get_u32(&t->position[at + 4u])) -
                        (uint64_t)(int64_t)y0;
    const uint64_t d = (lean || (t->position_wide != 0u)) ? (dy * t->position_scale)
                                                 : (dy * (uint32_t)t->position_scale);
    const int32_t a0 = ecam_i32(ecam_get_u32(&t->slope[at]));
    const int32_t a1 = ecam_i32(ecam_get_u32(&t->slope[at + 4u]));
    const int32_t b0 = ecam_i32(ecam_get_u32(&t->curvature[at]));
    const int32_t b1 = ecam_i32(ecam_get_u32(&t->curvature[at + 4u]));
    const int32_t *m = t->multiplier;
    uint64_t r = ecam_mac(ecam_mac(ecam_mac(ecam_mac(6u * d, a0, m[0]), a1, m[1]), b0, m[2]), b1, m[3]);

    if (slope) {
        r = 4u * ecam_mac(ecam_mac(ecam_mac(ecam_mac(0u - 15u * d, a0, m[4]), a1, m[5]), b0, m[6]),
                          b1, m[7]) +
            ecam_mulshift(t, 5u * r, tau);
        r = 3u * ecam_mac(ecam_mac(ecam_mac(ecam_mac(10u * d, a0, m[8]), a1, m[9]), b0, m[10]),
                          b1, m[11]) +
            ecam_mulshift(t, r, tau);
        r = ecam_mac(ecam_mulshift(t, r, tau), b0, 2 * m[12]);
        return ecam_slope_out(t, ecam_mac(ecam_mulshift(t, r, tau), a0, m[13]));
    }
    r = ecam_mac(ecam_mac(ecam_mac(ecam_mac(ecam_mulshift(t, r, tau) - 15u * d, a0, m[4]), a1, m[5]),
                          b0, m[6]),
                 b1, m[7]);
    r = ecam_mac(ecam_mac(ecam_mac(ecam_mac(ecam_mulshift(t, r, tau) + 10u * d, a0, m[8]), a1, m[9]),
                          b0, m[10]),
                 b1, m[11]);
    r = ecam_mac(ecam_mulshift(t, r, tau), b0, m[12]);
    r = ecam_mac(ecam_mulshift(t, r, tau), a0, m[13]);
    r = ecam_mulshift(t, r, tau) + t->round;
    if (lean || (t->position_wide != 0u)) {
        return ecam_out(t, r + ((uint64_t)(int64_t)y0 * t->position_scale));
    }
    return ecam_out(t, ecam_mac(r, y0, (int32_t)(uint32_t)t->position_scale));
}

#endif

/* Steps 4 and 6 of a linear table: q = c1 = D = Y1 - Y0 (W = Qy). */
static ECAM_INLINE int32_t ecam_linear_slope_at(const ecam_table *t, uint32_t i)
{
    const uint8_t *p = &t->position[(size_t)i * 4u];

    return ecam_slope_out(t, ecam_sext32(ecam_get_u32(&p[4])) - ecam_sext32(ecam_get_u32(p)));
}

static ECAM_COLD int32_t ecam_slope_outside(const ecam_table *t, int64_t m);

/* A kernel: steps 1..6 for one degree and step kind (constants after inlining). A master inside
 * [0, M) is the fast path; any other goes to the cold outside function (a tail call), which
 * wraps it and calls the kernel again, so the two frames never add up. */
static ECAM_INLINE int32_t ecam_kernel(const ecam_table *t, int64_t master, unsigned degree,
                                       bool pow2, bool slope)
{
    int64_t m = master;
    uint32_t tau = 0u;
    uint32_t i;

#if ECAM_WORD_BITS == 64
    if ((uint64_t)m >= t->master_limit) { /* also every negative m */
#else
    if ((uint64_t)m >= t->master_counts) {
#endif
        if (degree != 1u) {
            return slope ? ecam_slope_outside(t, m) : t->position_outside(t, m);
        }
        /* Linear kernels have small frames: the plain wrap runs inline, without a second call
         * (the clamp and a net stroke's wrap go through position_outside). */
        if (t->periodic != ECAM_WRAP) {
            return slope ? ecam_slope_outside(t, m) : t->position_outside(t, m);
        }
        m = (int64_t)ecam_wrap(t, m);
    }
    i = ecam_locate(t, (uint32_t)m, pow2, &tau);
    if (degree == 1u) {
        return slope ? ecam_linear_slope_at(t, i) : ecam_linear_at(t, i, tau);
    }
    if (degree == 3u) {
        return ecam_cubic_at(t, i, tau, slope, false);
    }
    return ecam_quintic_at(t, i, tau, slope, false);
}

/* The position kernels (degree x step kind) and the slope kernels (degree); init picks one of
 * each. */
static int32_t ecam_position_linear_pow2(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 1u, true, false);
}

static int32_t ecam_position_linear(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 1u, false, false);
}

static int32_t ecam_position_cubic_pow2(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 3u, true, false);
}

static int32_t ecam_position_cubic(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 3u, false, false);
}

static int32_t ecam_position_quintic_pow2(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 5u, true, false);
}

static int32_t ecam_position_quintic(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 5u, false, false);
}

/* True when the interval index is a shift (h = 2^k). */
static bool ecam_pow2(const ecam_table *t)
{
    return t->step_mask != 0u || t->step_counts == 1u;
}

static int32_t ecam_slope_linear(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 1u, ecam_pow2(t), true); /* one copy: the step kind is a branch */
}

static int32_t ecam_slope_cubic(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 3u, ecam_pow2(t), true); /* one copy: the step kind is a branch */
}

static int32_t ecam_slope_quintic(const ecam_table *t, int64_t m)
{
    return ecam_kernel(t, m, 5u, ecam_pow2(t), true); /* one copy: the step kind is a branch */
}

/* ------------------------------------------------------------------------------------------ */
/* General kernels: any scale, one coefficient at a time (small frames, more instructions)    */
/* ------------------------------------------------------------------------------------------ */


/* c_k of the interval at byte offset `at`, exactly (FORMAT.md step 4), from the stored words. */
static ECAM_COLD uint64_t ecam_coefficient(const ecam_table *t, size_t at, unsigned k)
{
    const uint64_t y0 = ecam_scaled_any(&t->position[at], t->position_scale);
    const uint64_t d = ecam_scaled_any(&t->position[at + 4u], t->position_scale) - y0;
    uint64_t a0;
    uint64_t a1;
    uint64_t b0;
    uint64_t b1;

    if (t->degree == 1u) {
        return d;
    }
    a0 = ecam_scaled_any(&t->slope[at], t->slope_scale);
    a1 = ecam_scaled_any(&t->slope[at + 4u], t->slope_scale);
    if (k == 1u) {
        return a0;
    }
    if (t->degree == 3u) {
        return k == 2u ? 3u * d - 2u * a0 - a1 : a0 + a1 - 2u * d;
    }
    b0 = ecam_scaled_any(&t->curvature[at], t->curvature_scale);
    b1 = ecam_scaled_any(&t->curvature[at + 4u], t->curvature_scale);
    if (k == 2u) {
        return b0;
    }
    if (k == 3u) {
        return 10u * d - 6u * a0 - 4u * a1 - 3u * b0 + b1;
    }
    if (k == 4u) {
        return 8u * a0 + 7u * a1 + 3u * b0 - 15u * d - 2u * b1;
    }
    return 6u * d - 3u * a0 - 3u * a1 - b0 + b1;
}

/* Steps 2..6 with any scale, for a master inside [0, M): the kernels of a table whose scales are
 * too wide for the 32-bit cores' fast kernels, or whose final position shift is 0. */
static ECAM_COLD int32_t ecam_general_local(const ecam_table *t, uint32_t local, bool slope)
{
    const unsigned n = t->degree;
    uint32_t tau32 = 0u;
    uint32_t i;
    size_t at;
    uint64_t tau;
    uint64_t r;
    unsigned k;

    i = ecam_locate(t, local, ecam_pow2(t), &tau32);
    at = (size_t)i * 4u;
    tau = tau32;
    r = (slope ? n : 1u) * ecam_coefficient(t, at, n);

    for (k = n - 1u; k >= 1u; k--) {
        r = (slope ? k : 1u) * ecam_coefficient(t, at, k) + ecam_asr(r * tau, t->tau_bits);
    }
    if (slope) {
        return ecam_slope_out(t, r);
    }
    r = ecam_scaled_any(&t->position[at], t->position_scale) + ecam_asr(r * tau, t->tau_bits) +
        t->half;
    return ecam_i32((uint32_t)ecam_asr(r, t->work_bits));
}

/* Step 1 (a master inside [0, M) goes on by a tail call), then ecam_general_local. */
static int32_t ecam_general(const ecam_table *t, int64_t m, bool slope)
{
    if ((uint64_t)m >= t->master_limit) {
        return slope ? ecam_slope_outside(t, m) : t->position_outside(t, m);
    }
    return ecam_general_local(t, (uint32_t)m, slope);
}

static int32_t ecam_position_general(const ecam_table *t, int64_t m)
{
    return ecam_general(t, m, false);
}

static int32_t ecam_slope_general(const ecam_table *t, int64_t m)
{
    return ecam_general(t, m, true);
}

/* ------------------------------------------------------------------------------------------ */
/* Entry points                                                                               */
/* ------------------------------------------------------------------------------------------ */

/* Step 1 for a master outside [0, M) (the position_outside of tables without a net stroke): the
 * wrap of a periodic table, then the kernel again with the master inside the period (a tail
 * call: this frame is gone before the kernel runs), or the clamp of a non-periodic table: the
 * held end position, slope 0. */
static ECAM_COLD int32_t ecam_position_outside(const ecam_table *t, int64_t m)
{
    if (t->periodic != ECAM_CLAMP) {
        return t->position_kernel(t, (int64_t)ecam_wrap(t, m));
    }
    return m < 0 ? t->end_position[0] : t->end_position[1];
}

static ECAM_COLD int32_t ecam_slope_outside(const ecam_table *t, int64_t m)
{
    if (t->periodic != ECAM_CLAMP) { /* the slope has no net term */
        return t->slope_kernel(t, (int64_t)ecam_wrap(t, m));
    }
    return 0;
}

/* (floor(u / d), u mod d) for any u < 2^64 and 1 <= d < 2^32, with mu = floor((2^64 - 1) / d):
 * mu > 2^64 / d - 1 makes hi(u mu) > u / d - 1, so it is floor(u / d) or one less, and one
 * correction makes both exact (Barrett, no divide). */
static ECAM_INLINE uint64_t ecam_divmod(uint64_t u, uint32_t d, uint64_t mu, uint64_t *rest)
{
    uint64_t q = ecam_mulhi_64x64(u, mu);
    uint64_t r = u - (q * d); /* below 2d */

    if (r >= d) {
        r -= d;
        q++;
    }
    *rest = r;
    return q;
}

/* Step 1 with its quotient: m mod M, and k = floor(m / M) in *turns (as int64 bits), for every
 * int64 m without a divide. u = m + 2^63 (the sign bit flipped) lies in [0, 2^64); with
 * mu = floor((2^64 - 1) / M) > 2^64 / M - 1, q = hi(u mu) is floor(u / M) or one less, so
 * r = u - q M lies in [0, 2M), below 2^32 (exact in 32 bits), and one correction makes q and r
 * exact. Then m = u - 2^63 with 2^63 = period_bias M + mod_offset. */
static ECAM_INLINE uint32_t ecam_wrap_turns(const ecam_table *t, int64_t m, uint64_t *turns)
{
#if ECAM_HAVE_INT128
    /* The signed reduction of ecam_wrap, keeping its quotient. */
    const ecam_int128 product = (ecam_int128)m * (ecam_int128)(int64_t)t->mod_recip;
    int64_t q = (int64_t)(product >= 0 ? product >> 64 : ~(~product >> 64));
    const int64_t r = ecam_i64((uint64_t)m - (uint64_t)q * t->master_counts);

    if (r < 0) {
        *turns = (uint64_t)q - 1u;
        return (uint32_t)r + t->master_counts;
    }
    if (r >= (int64_t)t->master_counts) {
        *turns = (uint64_t)q + 1u;
        return (uint32_t)r - t->master_counts;
    }
    *turns = (uint64_t)q;
    return (uint32_t)r;
#else
    const uint64_t u = (uint64_t)m ^ ECAM_SIGN_BIT64;
    uint64_t q = ecam_mulhi_64x64(u, t->mod_recip);
    uint32_t r = (uint32_t)u - ((uint32_t)q * t->master_counts);

    if (r >= t->master_counts) {
        r -= t->master_counts;
        q++;
    }
    q -= t->period_bias;
    if (r >= t->mod_offset) {
        *turns = q;
        return r - t->mod_offset;
    }
    *turns = q - 1u;
    return r + t->mod_complement;
#endif
}

/* The fractional part of step 7's term for k = turns whole periods (int64 bits), modulo 2^32:
 * with N = A D + B (0 < B < D) and k = kh D + kl (0 <= kl < D), floor((k B + floor(D/2)) / D) =
 * kh B + floor((kl B + floor(D/2)) / D), whose numerator is below D^2 < 2^64: no product leaves
 * 64 bits, no divide. kh and kl by the biased floor division of the wrap: k + 2^63 = q D + r and
 * 2^63 = net_bias D + net_bias_rest. Inline: the kernel runs after this frame is gone. */
static ECAM_INLINE uint32_t ecam_net_fraction(const ecam_table *t, uint64_t turns)
{
    uint64_t rest = 0u;
    uint64_t kh = ecam_divmod(turns ^ ECAM_SIGN_BIT64, t->net_den, t->net_recip, &rest) - t->net_bias;
    uint64_t kl;
    uint64_t last;

    if (rest >= t->net_bias_rest) {
        kl = rest - t->net_bias_rest;
    } else {
        kl = (rest + t->net_den) - t->net_bias_rest;
        kh--;
    }
#if ECAM_WORD_BITS != 64 /* (64-bit cores: the 64-bit quotient is one multiply already) */
    if (t->net_den <= ECAM_NET_SMALL_DEN) {
        /* x = kl B + floor(D/2) < 2^32 (kl, B < D <= 2^16): a 32-bit Barrett quotient with
         * mu = floor((2^32 - 1) / D), which is the high word of net_recip: floor((2^64 - 1) /
         * (D 2^32)) has no integer above floor((2^32 - 1) / D), as no multiple of D lies in
         * (2^32 - 1, 2^32). Then x / D - 2 < q <= x / D: one correction. */
        const uint32_t x = ((uint32_t)kl * t->net_rest) + t->net_half;
        uint32_t q = (uint32_t)(((uint64_t)x * (uint32_t)(t->net_recip >> 32)) >> 32);

        if ((x - (q * t->net_den)) >= t->net_den) {
            q++;
        }
        return ((uint32_t)kh * t->net_rest) + q;
    }
#endif
    last = ecam_divmod((kl * t->net_rest) + t->net_half, t->net_den, t->net_recip, &rest);
    return ((uint32_t)kh * t->net_rest) + (uint32_t)last;
}

/* Step 7 for a master outside [0, M) of a table with a net stroke N/D (its position_outside):
 * k = floor(m / M) whole periods add floor((k N + floor(D/2)) / D) = k A + floor((k B +
 * floor(D/2)) / D), taken modulo 2^32 (the int32 wrap); for D = 1 (B = 0) one multiply. The
 * kernel then runs with the master inside the period. */
static ECAM_INLINE uint32_t ecam_net_term(const ecam_table *t, uint64_t turns)
{
    uint32_t term = (uint32_t)turns * t->net_whole;

    if (t->net_rest != 0u) {
        term += ecam_net_fraction(t, turns);
    }
    return term;
}

/* The kernel continues with the term passed in (a tail call: this frame is gone before the
 * kernel's is made, so a net stroke adds nothing to the stack per call). */
static ECAM_COLD int32_t ecam_position_net_outside(const ecam_table *t, int64_t m)
{
    uint64_t turns = 0u;
    const uint32_t local = ecam_wrap_turns(t, m, &turns);

    return t->position_at(t, local, ecam_net_term(t, turns));
}

/* The same for a linear table with a whole net stroke (D = 1), with steps 2..5 inline: its kernel
 * is so small that a second dispatch and a frame would cost as much as the lookup itself. The
 * position_outside of those tables, by step kind. */
static ECAM_INLINE int32_t ecam_linear_whole_at(const ecam_table *t, int64_t m, bool pow2)
{
    uint64_t turns = 0u;
    uint32_t tau = 0u;
    const uint32_t local = ecam_wrap_turns(t, m, &turns);
    const uint32_t i = ecam_locate(t, local, pow2, &tau);

    return ecam_i32((uint32_t)ecam_linear_at(t, i, tau) + ((uint32_t)turns * t->net_whole));
}

static ECAM_COLD int32_t ecam_linear_whole_pow2(const ecam_table *t, int64_t m)
{
    return ecam_linear_whole_at(t, m, true);
}

static ECAM_COLD int32_t ecam_linear_whole(const ecam_table *t, int64_t m)
{
    return ecam_linear_whole_at(t, m, false);
}

/* Steps 2..6 of one degree for a master inside [0, M): the position (with the net term of step 7
 * added modulo 2^32) or the slope. */
static ECAM_INLINE int32_t ecam_value_at(const ecam_table *t, uint32_t i, uint32_t tau, unsigned degree,
                                         bool slope)
{
    if (degree == 1u) {
        return slope ? ecam_linear_slope_at(t, i) : ecam_linear_at(t, i, tau);
    }
    if (degree == 3u) {
        return ecam_cubic_at(t, i, tau, slope, true);
    }
    return ecam_quintic_at(t, i, tau, slope, true);
}

/* The position of a master inside [0, M) plus a term (the continuation of a net stroke's wrap). */
static ECAM_INLINE int32_t ecam_position_term_at(const ecam_table *t, uint32_t local, uint32_t term,
                                                 unsigned degree, bool pow2)
{
    uint32_t tau = 0u;
    const uint32_t i = ecam_locate(t, local, pow2, &tau);

    return ecam_i32((uint32_t)ecam_value_at(t, i, tau, degree, false) + term);
}

/* Both outputs of a master inside [0, M) in one pass (one interval search; the position plus a
 * term): the whole of ecam_table_lookup, reached by a tail call, so one frame per call. */
static ECAM_INLINE void ecam_lookup_term_at(const ecam_table *t, int32_t *position, uint32_t local,
                                            uint32_t term, int32_t *slope, unsigned degree, bool pow2)
{
    uint32_t tau = 0u;
    uint32_t i;

    if (position != NULL) {
        *position = ecam_position_term_at(t, local, term, degree, pow2);
    }
    if (slope != NULL) {
        /* the interval again (a few instructions): only the master stays live across the
         * position, which keeps the quintic's frame at 64 B */
        i = ecam_locate(t, local, pow2, &tau);
        *slope = ecam_value_at(t, i, tau, degree, true);
    }
}

/* One of each per degree and step kind; init picks them with the kernels. */
static ECAM_LEAN int32_t ecam_position_at_linear_pow2(const ecam_table *t, uint32_t local, uint32_t term)
{
    return ecam_position_term_at(t, local, term, 1u, true);
}

static ECAM_LEAN int32_t ecam_position_at_linear(const ecam_table *t, uint32_t local, uint32_t term)
{
    return ecam_position_term_at(t, local, term, 1u, false);
}

static ECAM_LEAN int32_t ecam_position_at_cubic_pow2(const ecam_table *t, uint32_t local, uint32_t term)
{
    return ecam_position_term_at(t, local, term, 3u, true);
}

static ECAM_LEAN int32_t ecam_position_at_cubic(const ecam_table *t, uint32_t local, uint32_t term)
{
    return ecam_position_term_at(t, local, term, 3u, false);
}

static ECAM_LEAN int32_t ecam_position_at_quintic_pow2(const ecam_table *t, uint32_t local, uint32_t term)
{
    return ecam_position_term_at(t, local, term, 5u, true);
}

static ECAM_LEAN int32_t ecam_position_at_quintic(const ecam_table *t, uint32_t local, uint32_t term)
{
    return ecam_position_term_at(t, local, term, 5u, false);
}

static int32_t ecam_position_at_general(const ecam_table *t, uint32_t local, uint32_t term)
{
    return ecam_i32((uint32_t)ecam_general_local(t, local, false) + term);
}

static ECAM_LEAN void ecam_lookup_at_linear_pow2(const ecam_table *t, int32_t *position, uint32_t local,
                                  uint32_t term, int32_t *slope)
{
    ecam_lookup_term_at(t, position, local, term, slope, 1u, true);
}

static ECAM_LEAN void ecam_lookup_at_linear(const ecam_table *t, int32_t *position, uint32_t local, uint32_t term,
                                  int32_t *slope)
{
    ecam_lookup_term_at(t, position, local, term, slope, 1u, false);
}

static ECAM_LEAN void ecam_lookup_at_cubic_pow2(const ecam_table *t, int32_t *position, uint32_t local,
                                  uint32_t term, int32_t *slope)
{
    ecam_lookup_term_at(t, position, local, term, slope, 3u, true);
}

static ECAM_LEAN void ecam_lookup_at_cubic(const ecam_table *t, int32_t *position, uint32_t local, uint32_t term,
                                  int32_t *slope)
{
    ecam_lookup_term_at(t, position, local, term, slope, 3u, false);
}

static ECAM_LEAN void ecam_lookup_at_quintic_pow2(const ecam_table *t, int32_t *position, uint32_t local,
                                  uint32_t term, int32_t *slope)
{
    ecam_lookup_term_at(t, position, local, term, slope, 5u, true);
}

static ECAM_LEAN void ecam_lookup_at_quintic(const ecam_table *t, int32_t *position, uint32_t local, uint32_t term,
                                  int32_t *slope)
{
    ecam_lookup_term_at(t, position, local, term, slope, 5u, false);
}

static void ecam_lookup_at_general(const ecam_table *t, int32_t *position, uint32_t local, uint32_t term,
                                   int32_t *slope)
{
    if (position != NULL) {
        *position = ecam_i32((uint32_t)ecam_general_local(t, local, false) + term);
    }
    if (slope != NULL) {
        *slope = ecam_general_local(t, local, true);
    }
}

/* ecam_table_lookup past [0, M): the clamp, or the wrap (and a net stroke's term), then both
 * outputs by a tail call. */
static ECAM_COLD void ecam_lookup_outside(const ecam_table *t, int32_t *position, int64_t m, int32_t *slope)
{
    uint64_t turns = 0u;
    uint32_t local;
    uint32_t term = 0u;

    if (t->periodic == ECAM_CLAMP) {
        if (position != NULL) {
            *position = m < 0 ? t->end_position[0] : t->end_position[1];
        }
        if (slope != NULL) {
            *slope = 0;
        }
        return;
    }
    if (t->periodic == ECAM_WRAP_NET) {
        local = ecam_wrap_turns(t, m, &turns);
        term = ecam_net_term(t, turns);
    } else {
        local = ecam_wrap(t, m);
    }
    t->lookup_at(t, position, local, term, slope);
}

/* ------------------------------------------------------------------------------------------ */
/* Version 3: the ramp (FORMAT.md step 8)                                                     */
/* ------------------------------------------------------------------------------------------ */

/* Steps 1 and 7 of any master with step 8's term: m mod M, and in *term the net term plus
 * S (m mod M), modulo 2^32 (the int32 wrap the position is returned in). */
static ECAM_INLINE uint32_t ecam_ramp_wrap(const ecam_table *t, int64_t m, uint32_t *term)
{
    uint64_t turns = 0u;
    uint32_t local = (uint32_t)m;
    uint32_t net = 0u;

    if ((uint64_t)m >= t->master_limit) { /* also every negative m */
        local = ecam_wrap_turns(t, m, &turns);
        net = ecam_net_term(t, turns);
    }
    *term = net + (local * t->ramp);
    return local;
}

/* The position kernel (and position_outside) of a version-3 table: the degree's continuation,
 * its term carrying the ramp (a tail call). */
static int32_t ecam_position_ramp(const ecam_table *t, int64_t m)
{
    uint32_t term = 0u;
    const uint32_t local = ecam_ramp_wrap(t, m, &term);

    return t->ramp_at(t, local, term);
}

/* Its position_at: a master already inside [0, M), a net term already formed. */
static int32_t ecam_position_at_ramp(const ecam_table *t, uint32_t local, uint32_t term)
{
    return t->ramp_at(t, local, term + (local * t->ramp));
}

/* Its slope kernel: the degree's for m mod M (the slope has no net term), plus S 2^16. */
static int32_t ecam_slope_ramp(const ecam_table *t, int64_t m)
{
    const int64_t local = ((uint64_t)m >= t->master_limit) ? (int64_t)ecam_wrap(t, m) : m;

    return ecam_i32((uint32_t)t->ramp_slope_kernel(t, local) + t->ramp_slope);
}

/* Its lookup_at: both outputs of a master inside [0, M), the position plus a net term. */
static void ecam_lookup_at_ramp(const ecam_table *t, int32_t *position, uint32_t local, uint32_t term,
                                int32_t *slope)
{
    if (position != NULL) {
        *position = t->ramp_at(t, local, term + (local * t->ramp));
    }
    if (slope != NULL) {
        *slope = ecam_i32((uint32_t)t->ramp_slope_kernel(t, (int64_t)local) + t->ramp_slope);
    }
}

/* The hot path: one indirect jump to the kernel chosen at init. */
int32_t ecam_table_position(const ecam_table *t, int64_t master_counts)
{
    if (t == NULL || t->position_kernel == NULL) {
        return ECAM_INVALID;
    }
    return t->position_kernel(t, master_counts);
}

/* Both outputs of one master position in one pass: one call of the degree's lookup_at (a tail
 * call, so the stack per call is that function's frame alone). */
void ecam_table_lookup(const ecam_table *t, int64_t master_counts, int32_t *position,
                       int32_t *slope)
{
    if (ecam_table_ready(t) == 0) {
        if (position != NULL) {
            *position = ECAM_INVALID;
        }
        if (slope != NULL) {
            *slope = ECAM_INVALID;
        }
        return;
    }
    if ((uint64_t)master_counts >= t->master_limit) { /* also every negative master */
        ecam_lookup_outside(t, position, master_counts, slope);
        return;
    }
    t->lookup_at(t, position, (uint32_t)master_counts, 0u, slope);
}

/* The velocity feed-forward ratio alone: one indirect jump to the slope kernel. */
int32_t ecam_table_slope(const ecam_table *t, int64_t master_counts)
{
    if (t == NULL || t->slope_kernel == NULL) {
        return ECAM_INVALID;
    }
    return t->slope_kernel(t, master_counts);
}

/* 1 when the table looks up. */
int ecam_table_ready(const ecam_table *t)
{
    return t != NULL && t->position_kernel != NULL && t->slope_kernel != NULL;
}

/* Why a table does not look up (or ECAM_OK). */
int ecam_table_status(const ecam_table *t)
{
    if (t == NULL) {
        return (int)ECAM_E_NULL;
    }
    if (ecam_table_ready(t) != 0) {
        return (int)ECAM_OK;
    }
    return (t->status != 0) ? (int)t->status : (int)ECAM_E_UNINITIALISED;
}

/* An all-zero table: not ready (what a failed init leaves, plus the failure code). */
static const ecam_table ecam_cleared;

/* ------------------------------------------------------------------------------------------ */
/* Loader: envelope and field rules                                                           */
/* ------------------------------------------------------------------------------------------ */

/* The header fields the rules and the lookup need, decoded once. */
typedef struct ecam_header {
    uint64_t tau_recip;
    uint64_t net_num;         /* N (int64 bits); 0 in version 1 */
    uint32_t net_den;         /* D; 1 in version 1 */
    uint32_t ramp;            /* version 3: S = floor(N / (D M)) as int32 bits (rule -36); else 0 */
    unsigned version;
    uint32_t points;
    uint32_t master_counts;
    uint32_t step_counts;
    uint32_t payload_bytes;
    unsigned degree;
    unsigned flags;
    int step_shift;
    unsigned tau_bits;
    unsigned work_bits;
    unsigned slope_bits;
    unsigned curvature_bits;
    unsigned slope_preshift;
    unsigned position_bits;
} ecam_header;

/* Number of int32 arrays in the payload (V in FORMAT.md) for a supported degree, else 0. */
static unsigned ecam_arrays_for_degree(unsigned degree)
{
    unsigned arrays = 0u;

    if (degree == 1u) {
        arrays = 1u;
    } else if (degree == 3u) {
        arrays = 2u;
    } else if (degree == 5u) {
        arrays = 3u;
    } else {
        arrays = 0u;
    }
    return arrays;
}

/* The checks FORMAT.md lists before the field rules, in the order it lists them. */
static ecam_status ecam_check_envelope(const uint8_t *blob, size_t len)
{
    if (len < (size_t)ECAM_HEADER_BYTES) {
        return ECAM_E_SHORT;
    }
    if (blob[0] != (uint8_t)'E' || blob[1] != (uint8_t)'C' || blob[2] != (uint8_t)'A' ||
        blob[3] != (uint8_t)'M') {
        return ECAM_E_MAGIC;
    }
    if ((ecam_get_u16(&blob[ECAM_OFF_VERSION]) < 1u) || (ecam_get_u16(&blob[ECAM_OFF_VERSION]) > 3u)) {
        return ECAM_E_VERSION;
    }
    if (ecam_get_u16(&blob[ECAM_OFF_HEADER_BYTES]) != (uint32_t)ECAM_HEADER_BYTES) {
        return ECAM_E_HEADER_SIZE;
    }
    if (ecam_crc32(blob, ECAM_OFF_HEADER_CRC) != ecam_get_u32(&blob[ECAM_OFF_HEADER_CRC])) {
        return ECAM_E_HEADER_CRC;
    }
    return ECAM_OK;
}

/* Copies the header fields (no checks yet). */
static void ecam_read_header(const uint8_t *blob, ecam_header *h)
{
    const uint32_t shift_byte = blob[ECAM_OFF_STEP_SHIFT];

    h->degree = blob[ECAM_OFF_DEGREE];
    h->flags = blob[ECAM_OFF_FLAGS];
    h->step_shift = shift_byte < 128u ? (int)shift_byte : (int)shift_byte - 256;
    h->tau_bits = blob[ECAM_OFF_TAU_BITS];
    h->work_bits = blob[ECAM_OFF_WORK_BITS];
    h->slope_bits = blob[ECAM_OFF_SLOPE_BITS];
    h->curvature_bits = blob[ECAM_OFF_CURVATURE_BITS];
    h->slope_preshift = blob[ECAM_OFF_SLOPE_PRESHIFT];
    h->points = ecam_get_u32(&blob[ECAM_OFF_POINTS]);
    h->master_counts = ecam_get_u32(&blob[ECAM_OFF_MASTER_COUNTS]);
    h->step_counts = ecam_get_u32(&blob[ECAM_OFF_STEP_COUNTS]);
    h->position_bits = blob[ECAM_OFF_POSITION_BITS];
    h->tau_recip = ecam_get_u64(&blob[ECAM_OFF_TAU_RECIP]);
    h->payload_bytes = ecam_get_u32(&blob[ECAM_OFF_PAYLOAD_BYTES]);
    h->version = ecam_get_u16(&blob[ECAM_OFF_VERSION]);
    h->net_num = 0u;
    h->net_den = 1u;
    h->ramp = 0u;
    if (h->version >= 2u) { /* bytes 48..59: the net stroke N (int64), D (uint32) */
        h->net_num = ecam_get_u64(&blob[ECAM_OFF_RESERVED_B]);
        h->net_den = ecam_get_u32(&blob[ECAM_OFF_RESERVED_B + 8u]);
    }
}

/* Reserved space must be zero so that a future version can use it without ambiguity (bytes
 * 48..59 hold the net stroke in version 2). */
static int ecam_reserved_zero(const uint8_t *blob, unsigned version)
{
    unsigned n;
    unsigned any = 0u;

    for (n = ECAM_OFF_RESERVED_A; n < ECAM_OFF_TAU_RECIP; n++) {
        any |= blob[n];
    }
    for (n = ECAM_OFF_RESERVED_B; (version == 1u) && (n < ECAM_OFF_HEADER_CRC); n++) {
        any |= blob[n];
    }
    return any == 0u;
}

/* Greatest common divisor (Euclid; init only, so the remainders may divide). */
static uint64_t ecam_gcd(uint64_t a, uint64_t b)
{
    uint64_t x = a;
    uint64_t y = b;

    while (y != 0u) {
        const uint64_t rest = x % y;

        x = y;
        y = rest;
    }
    return x;
}

/* Rule ECAM_E_NET_STROKE: N/D reduced, 1 <= D, |N| < D * 2^31, and N = 0 unless periodic. */
static bool ecam_net_stroke_ok(const ecam_header *h)
{
    const bool negative = (h->net_num & ECAM_SIGN_BIT64) != 0u;
    const uint64_t magnitude = negative ? (0u - h->net_num) : h->net_num; /* |N|, 2^63 included */

    if (h->net_den == 0u) {
        return false;
    }
    if (ecam_gcd(magnitude, h->net_den) != 1u) { /* 0/1 is the only form of "none" */
        return false;
    }
    if (magnitude >= ((uint64_t)h->net_den << 31)) {
        return false;
    }
    return (magnitude == 0u) || ((h->flags & 1u) != 0u);
}

/* Rule ECAM_E_RAMP (version 3; after ECAM_E_NET_STROKE, so D >= 1 and |N| < D 2^31): a net stroke
 * N != 0 and S = floor(N / (D M)) within +-(2^15 - 1), so that S 2^16 fits the slope. S goes to
 * h->ramp. D M < 2^63: the division is exact in 64 bits (init only). */
static bool ecam_ramp_ok(ecam_header *h)
{
    const bool negative = (h->net_num & ECAM_SIGN_BIT64) != 0u;
    const uint64_t magnitude = negative ? (0u - h->net_num) : h->net_num;
    const uint64_t period = (uint64_t)h->net_den * h->master_counts;
    uint64_t whole = magnitude / period;

    if (h->version != 3u) {
        return true;
    }
    if (negative && ((magnitude % period) != 0u)) {
        whole++; /* floor of a negative quotient */
    }
    if ((magnitude == 0u) || (whole > ECAM_MAX_RAMP)) {
        return false;
    }
    h->ramp = negative ? (0u - (uint32_t)whole) : (uint32_t)whole;
    return true;
}

/* R = ceil(2^(32+F) / h) checked by multiplication: R * h >= 2^(32+F) > (R - 1) * h. */
static int ecam_tau_recip_ok(uint64_t r, uint32_t h, unsigned f)
{
    const uint64_t target = UINT64_C(1) << (32u + f); /* f <= 30 checked before */
    uint64_t hi;
    uint64_t lo;

    ecam_mul_64x64(r, h, &hi, &lo);
    return hi == 0u && lo >= target && lo - h < target;
}

/* Geometry rules (points, M, h, step_shift, F, R) in FORMAT.md's check order. */
static ecam_status ecam_check_geometry(const ecam_header *h)
{
    const uint32_t step = h->step_counts;
    const bool pow2 = (step != 0u) && ((step & (step - 1u)) == 0u);
    unsigned k = 0u;

    if (h->points < 2u) {
        return ECAM_E_POINTS;
    }
    if (h->master_counts < ECAM_MIN_MASTER_COUNTS || h->master_counts > ECAM_MAX_MASTER_COUNTS) {
        return ECAM_E_MASTER_COUNTS;
    }
    if (step < 1u || step > ECAM_MAX_STEP_COUNTS ||
        (uint64_t)(h->points - 1u) * step != h->master_counts) {
        return ECAM_E_STEP_COUNTS;
    }
    while (pow2 && ((UINT32_C(1) << k) != step)) {
        k++;
    }
    if (h->step_shift != (pow2 ? (int)k : -1)) {
        return ECAM_E_STEP_SHIFT;
    }
    if (h->tau_bits > ECAM_MAX_TAU_BITS || step > (UINT32_C(1) << h->tau_bits) ||
        (pow2 && (h->tau_bits != k))) {
        return ECAM_E_TAU_BITS;
    }
    if (ecam_tau_recip_ok(h->tau_recip, step, h->tau_bits) == 0) {
        return ECAM_E_TAU_RECIP;
    }
    return ECAM_OK;
}

/* Fixed-point format rules (Qy, W, Qa, Qb, P) in FORMAT.md's check order. */
static ecam_status ecam_check_format(const ecam_header *h)
{
    const unsigned w = h->work_bits;
    const unsigned scaled = ECAM_SLOPE_FRACTION_BITS + h->tau_bits + w;

    if (h->position_bits > ECAM_MAX_POSITION_BITS) {
        return ECAM_E_POSITION_BITS;
    }
    if (w > ECAM_MAX_WORK_BITS || w < h->position_bits ||
        (h->degree == 1u && w != h->position_bits)) {
        return ECAM_E_WORK_BITS;
    }
    if (h->slope_bits > w || (h->degree == 1u && h->slope_bits != 0u)) {
        return ECAM_E_SLOPE_BITS;
    }
    if (h->curvature_bits > w || (h->degree != 5u && h->curvature_bits != 0u)) {
        return ECAM_E_CURVATURE_BITS;
    }
    /* 0 <= P holds by type; 16 + F + W - P must lie in 0..63. */
    if (h->slope_preshift > scaled || scaled - h->slope_preshift > ECAM_MAX_SHIFT) {
        return ECAM_E_SLOPE_PRESHIFT;
    }
    return ECAM_OK;
}

/* Every field rule of FORMAT.md, in its order, on a header whose CRC matched (h->ramp set). */
static ecam_status ecam_check_fields(const uint8_t *blob, ecam_header *h)
{
    ecam_status status;

    if (ecam_arrays_for_degree(h->degree) == 0u) {
        return ECAM_E_DEGREE;
    }
    if ((h->flags & ~1u) != 0u) {
        return ECAM_E_FLAGS;
    }
    if (ecam_reserved_zero(blob, h->version) == 0) {
        return ECAM_E_RESERVED;
    }
    status = ecam_check_geometry(h);
    if (status == ECAM_OK) {
        status = ecam_check_format(h);
    }
    if (status == ECAM_OK &&
        (uint64_t)h->payload_bytes !=
            (uint64_t)h->points * 4u * ecam_arrays_for_degree(h->degree)) {
        status = ECAM_E_PAYLOAD_BYTES;
    }
    if ((status == ECAM_OK) && !ecam_net_stroke_ok(h)) {
        status = ECAM_E_NET_STROKE;
    }
    if ((status == ECAM_OK) && !ecam_ramp_ok(h)) {
        status = ECAM_E_RAMP;
    }
    return status;
}

/* ------------------------------------------------------------------------------------------ */
/* Loader: the overflow proof (FORMAT.md "Overflow proof"), in 128-bit integers               */
/* ------------------------------------------------------------------------------------------ */

/* A 128-bit two's-complement integer: the proof's values reach about 2^85. The helpers work in
 * place through pointers, which keeps the loader's stack small on 32-bit cores. */
typedef struct ecam_wide {
    uint64_t hi;
    uint64_t lo;
} ecam_wide;

/* What the proof needs from the format, computed once. */
typedef struct ecam_proof {
    const uint8_t *position;
    const uint8_t *slope;
    const uint8_t *curvature;
    ecam_wide reach_limit;     /* Dn * (2^31 - 1) * 2^W */
    uint64_t product_limit;    /* largest r with r * T < 2^63 (T = 2^F - 1 > 0) */
    uint64_t tau_recip;        /* R */
    uint64_t slope_limit;      /* 2^31 - 1 less a version-3 ramp's |S| 2^16 */
    unsigned degree;
    unsigned has_tau;          /* T > 0 */
    unsigned position_shift;   /* W - Qy */
    unsigned slope_shift;      /* W - Qa */
    unsigned curvature_shift;  /* W - Qb */
    unsigned work_bits;        /* W */
    unsigned preshift;         /* P */
    unsigned out_shift;        /* f = 16 + F + W - P */
    unsigned bernstein_scale;  /* Dn */
} ecam_proof;

/* *w = x * 2^s for 0 <= s <= 63. */
static void ecam_wide_shl(ecam_wide *w, uint64_t x, unsigned s)
{
    w->lo = x << s;
    w->hi = (uint64_t)0u;
    if (s > 0u) {
        const unsigned back = 64u - s;

        w->hi = x >> back;
    }
}

/* *w = the stored int32 bits times 2^s (s <= 40), sign-extended to 128 bits. */
static void ecam_wide_scaled(ecam_wide *w, uint32_t bits, unsigned s)
{
    const uint64_t v = ecam_sext32(bits);

    w->lo = v << s;
    w->hi = (s == 0u) ? ecam_asr_any(v, 64u) : ecam_asr(v, 64u - s);
}

/* *acc += *a * k for a small signed constant k (|k| <= 15), modulo 2^128. */
static ECAM_COLD void ecam_wide_mac(ecam_wide *acc, const ecam_wide *a, int k)
{
    const uint64_t magnitude = (uint64_t)((k < 0) ? -k : k);
    uint64_t carry;
    uint64_t lo;
    uint64_t hi;

    ecam_mul_64x64(a->lo, magnitude, &carry, &lo);
    hi = (a->hi * magnitude) + carry;
    if (k < 0) {
        hi = ~hi + ((lo == 0u) ? 1u : 0u);
        lo = ~lo + 1u;
    }
    acc->lo += lo;
    acc->hi += hi + ((acc->lo < lo) ? 1u : 0u);
}

/* *out = |*a|, as an unsigned magnitude (every value of the proof is far from -2^127). */
static void ecam_wide_abs(ecam_wide *out, const ecam_wide *a)
{
    *out = *a;
    if ((a->hi & ECAM_SIGN_BIT64) != 0u) {
        out->hi = ~a->hi + ((a->lo == 0u) ? 1u : 0u);
        out->lo = ~a->lo + 1u;
    }
}

/* *acc += *b (unsigned magnitudes) plus a small constant. */
static void ecam_wide_add(ecam_wide *acc, const ecam_wide *b, uint64_t plus)
{
    const uint64_t lo = acc->lo + b->lo;
    const uint64_t carry = (lo < acc->lo) ? (uint64_t)1u : (uint64_t)0u;
    const uint64_t sum = lo + plus;

    acc->hi += b->hi + carry + ((sum < lo) ? 1u : 0u);
    acc->lo = sum;
}

/* Unsigned *a <= *b. */
static bool ecam_wide_at_most(const ecam_wide *a, const ecam_wide *b)
{
    return (a->hi < b->hi) || ((a->hi == b->hi) && (a->lo <= b->lo));
}

/* Magnitude r satisfies r * T < 2^63. */
static bool ecam_product_ok(const ecam_proof *p, const ecam_wide *r)
{
    return (p->has_tau == 0u) || ((r->hi == 0u) && (r->lo <= p->product_limit));
}

/* Magnitude below 2^63. */
static bool ecam_int64_ok(const ecam_wide *r)
{
    return (r->hi == 0u) && (r->lo < ECAM_SIGN_BIT64);
}

/* The Hermite coefficients c_1..c_n of the interval at byte offset `at`, exactly
 * (FORMAT.md step 4): c_k = sum over (D, a0, a1, b0, b1) of weight * value. */
static ECAM_COLD void ecam_exact_coefficients(const ecam_proof *p, size_t at, ecam_wide c[6])
{
    static const int8_t cubic[4][5] = {{0, 0, 0, 0, 0}, {0, 1, 0, 0, 0}, {3, -2, -1, 0, 0}, {-2, 1, 1, 0, 0}};
    static const int8_t quintic[6][5] = {{0, 0, 0, 0, 0},     {0, 1, 0, 0, 0},    {0, 0, 0, 1, 0},
                                         {10, -6, -4, -3, 1}, {-15, 8, 7, 3, -2}, {6, -3, -3, -1, 1}};
    const uint8_t *arrays[5] = {p->position, p->slope, p->slope, p->curvature, p->curvature};
    const unsigned shifts[5] = {p->position_shift, p->slope_shift, p->slope_shift, p->curvature_shift,
                                p->curvature_shift};
    const unsigned values = (p->degree + 1u) / 2u * 2u - 1u; /* 1, 3, 5: D; D, a0, a1; all five */
    ecam_wide value;
    unsigned k;
    unsigned v;

    for (k = 1u; k <= p->degree; k++) {
        c[k].hi = 0u;
        c[k].lo = 0u;
        for (v = 0u; v < values; v++) {
            int weight = 1; /* linear: c1 = D */

            if (p->degree == 3u) {
                weight = cubic[k][v];
            } else if (p->degree == 5u) {
                weight = quintic[k][v];
            } else {
                /* degree 1 */
            }
            if (weight == 0) {
                continue;
            }
            /* value 0 is D = Y1 - Y0; values 1..4 are a0, a1, b0, b1 (word i, i + 1, i, i + 1) */
            ecam_wide_scaled(&value, ecam_get_u32(&arrays[v][at + (((v % 2u) == 0u && v > 0u) ? 4u : 0u)]),
                             shifts[v]);
            if (v == 0u) {
                ecam_wide_mac(&c[k], &value, -weight);
                ecam_wide_scaled(&value, ecam_get_u32(&arrays[0][at + 4u]), shifts[0]);
            }
            ecam_wide_mac(&c[k], &value, weight);
        }
    }
}

/* Rule ECAM_E_POSITION_RANGE: Dn * |B_j| + Dn * n <= Dn * (2^31 - 1) * 2^W for j = 0..n, with
 * Dn * B_j = Dn * Y0 + sum_k weight[j][k] * c_k, weight = C(j, k) * Dn / C(n, k). */
static ECAM_COLD bool ecam_reach_ok(const ecam_proof *p, const ecam_wide *y0, const ecam_wide c[6])
{
    static const uint8_t cubic[4][4] = {{0u, 0u, 0u, 0u}, {0u, 1u, 0u, 0u}, {0u, 2u, 1u, 0u}, {0u, 3u, 3u, 3u}};
    static const uint8_t quintic[6][6] = {{0u, 0u, 0u, 0u, 0u, 0u},   {0u, 2u, 0u, 0u, 0u, 0u},
                                          {0u, 4u, 1u, 0u, 0u, 0u},   {0u, 6u, 3u, 1u, 0u, 0u},
                                          {0u, 8u, 6u, 4u, 2u, 0u},   {0u, 10u, 10u, 10u, 10u, 10u}};
    const unsigned n = p->degree;
    ecam_wide b;
    ecam_wide magnitude;
    unsigned j;
    unsigned k;

    for (j = 0u; j <= n; j++) {
        b.hi = 0u;
        b.lo = 0u;
        ecam_wide_mac(&b, y0, (int)p->bernstein_scale);
        for (k = 1u; k <= j; k++) {
            unsigned weight = 1u; /* linear: B_1 = Y0 + c1 */

            if (n == 3u) {
                weight = cubic[j][k];
            } else if (n == 5u) {
                weight = quintic[j][k];
            } else {
                /* degree 1 */
            }
            ecam_wide_mac(&b, &c[k], (int)weight);
        }
        ecam_wide_abs(&magnitude, &b);
        magnitude.lo += (uint64_t)p->bernstein_scale * n;
        magnitude.hi += (magnitude.lo < (uint64_t)p->bernstein_scale * n) ? 1u : 0u;
        if (!ecam_wide_at_most(&magnitude, &p->reach_limit)) {
            return false;
        }
    }
    return true;
}

/* Rules ECAM_E_SLOPE_PRODUCT and ECAM_E_SLOPE_RANGE for a bound q < 2^63 of |q_1|. */
static ECAM_COLD ecam_status ecam_slope_ok(const ecam_proof *p, uint64_t q)
{
    uint64_t s;
    ecam_wide product;
    ecam_wide limit;

    if (p->preshift >= ECAM_MAX_SHIFT) {
        s = (q > 0u) ? (uint64_t)1u : (uint64_t)0u; /* q < 2^63 <= 2^P */
    } else {
        s = (q >> p->preshift) + (((q & ((UINT64_C(1) << p->preshift) - 1u)) != 0u) ? 1u : 0u);
    }
    ecam_mul_64x64(s, p->tau_recip, &product.hi, &product.lo);
    if (!ecam_int64_ok(&product)) {
        return ECAM_E_SLOPE_PRODUCT;
    }
    ecam_wide_shl(&limit, p->slope_limit, p->out_shift);
    if (!ecam_wide_at_most(&product, &limit)) {
        return ECAM_E_SLOPE_RANGE;
    }
    return ECAM_OK;
}

/* Every rule of the overflow proof for interval i, in FORMAT.md's order. */
static ECAM_COLD ecam_status ecam_prove_interval(const ecam_proof *p, uint32_t i)
{
    const unsigned n = p->degree;
    const size_t at = (size_t)i * 4u;
    ecam_wide c[6];
    ecam_wide y0;
    ecam_wide r;
    ecam_wide magnitude;
    unsigned k;

    /* ECAM_E_POINT_RANGE: |Y_i| < 2^62 and |Y_(i+1)| < 2^62 */
    for (k = 0u; k < 2u; k++) {
        const size_t word = at + ((size_t)k * 4u);

        ecam_wide_scaled(&y0, ecam_get_u32(&p->position[word]), p->position_shift);
        ecam_wide_abs(&magnitude, &y0);
        if ((magnitude.hi != 0u) || (magnitude.lo >= (UINT64_C(1) << 62))) {
            return ECAM_E_POINT_RANGE;
        }
    }
    ecam_wide_scaled(&y0, ecam_get_u32(&p->position[at]), p->position_shift);
    ecam_exact_coefficients(p, at, c);
    /* ECAM_E_HORNER_RANGE: r_n = |c_n|, r_k = |c_k| + r_(k+1) + 1, r_k * T < 2^63 */
    ecam_wide_abs(&r, &c[n]);
    if (!ecam_product_ok(p, &r)) {
        return ECAM_E_HORNER_RANGE;
    }
    for (k = n - 1u; k >= 1u; k--) {
        ecam_wide_abs(&magnitude, &c[k]);
        ecam_wide_add(&r, &magnitude, 1u);
        if (!ecam_product_ok(p, &r)) {
            return ECAM_E_HORNER_RANGE;
        }
    }
    /* ECAM_E_SUM_RANGE: |Y_i| + r_1 + 2^W < 2^63 */
    ecam_wide_abs(&magnitude, &y0);
    ecam_wide_add(&r, &magnitude, UINT64_C(1) << p->work_bits);
    if (!ecam_int64_ok(&r)) {
        return ECAM_E_SUM_RANGE;
    }
    if (!ecam_reach_ok(p, &y0, c)) {
        return ECAM_E_POSITION_RANGE;
    }
    /* ECAM_E_SLOPE_HORNER_RANGE: q_n = n |c_n|, q_k = k |c_k| + q_(k+1) + 1, q_k * T < 2^63
     * (k = n..2), q_1 < 2^63 */
    r.hi = 0u;
    r.lo = 0u;
    ecam_wide_abs(&magnitude, &c[n]);
    ecam_wide_mac(&r, &magnitude, (int)n);
    for (k = n - 1u; k >= 1u; k--) {
        if (!ecam_product_ok(p, &r)) {
            return ECAM_E_SLOPE_HORNER_RANGE;
        }
        ecam_wide_abs(&magnitude, &c[k]);
        ecam_wide_mac(&r, &magnitude, (int)k);
        r.lo += 1u;
        r.hi += (r.lo == 0u) ? 1u : 0u;
    }
    if (!ecam_int64_ok(&r)) {
        return ECAM_E_SLOPE_HORNER_RANGE;
    }
    return ecam_slope_ok(p, r.lo);
}

/* The whole proof: every interval in order; the first failing rule's code. */
static ecam_status ecam_prove(const uint8_t *blob, const ecam_header *h)
{
    const uint8_t *payload = &blob[ECAM_HEADER_BYTES];
    const uint64_t tau_max = (UINT64_C(1) << h->tau_bits) - 1u;
    ecam_proof p;
    uint32_t i;
    ecam_status status = ECAM_OK;

    p.position = payload;
    p.slope = &payload[(size_t)h->points * 4u];
    p.curvature = &payload[(size_t)h->points * 8u];
    p.degree = h->degree;
    p.has_tau = (tau_max > 0u) ? (unsigned)1u : (unsigned)0u;
    p.product_limit = (tau_max > 0u) ? ((ECAM_SIGN_BIT64 - 1u) / tau_max) : (uint64_t)0u;
    p.tau_recip = h->tau_recip;
    p.slope_limit = (uint64_t)ECAM_INT32_LIMIT -
                    ((uint64_t)((ecam_i32(h->ramp) < 0) ? (0u - h->ramp) : h->ramp) << ECAM_SLOPE_FRACTION_BITS);
    p.position_shift = h->work_bits - h->position_bits;
    p.slope_shift = h->work_bits - h->slope_bits;
    p.curvature_shift = h->work_bits - h->curvature_bits;
    p.work_bits = h->work_bits;
    p.preshift = h->slope_preshift;
    p.out_shift = ECAM_SLOPE_FRACTION_BITS + h->tau_bits + h->work_bits - h->slope_preshift;
    p.bernstein_scale = 10u;
    if (h->degree == 1u) {
        p.bernstein_scale = 1u;
    } else if (h->degree == 3u) {
        p.bernstein_scale = 3u;
    } else {
        /* quintic: Dn = 10 */
    }
    ecam_wide_shl(&p.reach_limit, (uint64_t)p.bernstein_scale * ECAM_INT32_LIMIT, h->work_bits);
    for (i = 0u; ((i + 1u) < h->points) && (status == ECAM_OK); i++) {
        status = ecam_prove_interval(&p, i);
    }
    return status;
}

/* ------------------------------------------------------------------------------------------ */
/* Loader: binding the table                                                                  */
/* ------------------------------------------------------------------------------------------ */

/* Clamp of FORMAT.md step 1 for non-periodic tables: a stored end point rounded half up from
 * Q(Qy) to whole counts (the proof bounds it inside int32). */
static int32_t ecam_end_point(const uint8_t *position, uint32_t i, unsigned qy)
{
    const uint64_t halfy = qy > 0u ? UINT64_C(1) << (qy - 1u) : 0u;

    return ecam_i32((uint32_t)ecam_asr(ecam_sext32(ecam_get_u32(&position[(size_t)i * 4u])) + halfy, qy));
}

/* The position kernel of one degree and step kind. On 32-bit cores the fast cubic and quintic
 * kernels multiply 32x32, which needs every scale 2^(W - Q) <= 2^30; other tables use the
 * general kernel (same bits, more instructions). */
static ecam_position_kernel ecam_pick_kernel(const ecam_header *h, bool pow2)
{
    const unsigned w = h->work_bits;
    /* 32-bit cores: stored words times their scales are 32x32 products, which needs every
     * scale 2^(W - Q) <= 2^30, and the quintic's multipliers w * 2^(W - Q) (|w| <= 8 for slopes,
     * 3 for curvatures, twice that in the slope kernel) must fit int32. */
    const bool narrow = (ECAM_WORD_BITS == 64) ||
                        ((w - h->slope_bits <= 30u) &&
                         ((h->degree != 5u) || ((w - h->slope_bits <= 26u) && (w - h->curvature_bits <= 27u))));

    if (h->degree == 1u) {
        return pow2 ? ecam_position_linear_pow2 : ecam_position_linear;
    }
    if (!narrow) {
        return ecam_position_general;
    }
    if (h->degree == 3u) {
        return pow2 ? ecam_position_cubic_pow2 : ecam_position_cubic;
    }
    return pow2 ? ecam_position_quintic_pow2 : ecam_position_quintic;
}

/* The 32-bit cores' quintic multipliers w * 2^(W - Q) of the slope and curvature words (see
 * ecam_quintic_at); zero where they would not fit (the general kernel is used then). */
static void ecam_set_multipliers(const ecam_header *h, ecam_table *t)
{
    static const int8_t quintic[14] = {-3, -3, -1, 1, 8, 7, 3, -2, -6, -4, -3, 1, 1, 1};
    const unsigned sa = h->work_bits - h->slope_bits;
    const unsigned sb = h->work_bits - h->curvature_bits;

    if ((h->degree == 5u) && (sa <= 26u) && (sb <= 27u)) {
        unsigned k;

        for (k = 0u; k < 14u; k++) {
            /* entries 0, 1, 4, 5, 8, 9 and 13 multiply slope words, the others curvature words */
            const unsigned shift = (((k % 4u) < 2u) && (k < 12u)) || (k == 13u) ? sa : sb;
            t->multiplier[k] = quintic[k] * (int32_t)(UINT32_C(1) << shift);
        }
    }
}

/* The slope kernel of one degree (the general one where the fast kernels' scales do not fit). */
static ecam_slope_kernel ecam_pick_slope_kernel(const ecam_header *h)
{
    if (ecam_pick_kernel(h, true) == ecam_position_general) {
        return ecam_slope_general;
    }
    if (h->degree == 1u) {
        return ecam_slope_linear;
    }
    return h->degree == 3u ? ecam_slope_cubic : ecam_slope_quintic;
}

/* The continuations of one degree past the wrap and of ecam_table_lookup (the general ones
 * where the fast kernels' scales do not fit). */
static void ecam_pick_at(const ecam_header *h, ecam_table *t)
{
    const bool pow2 = h->step_shift >= 0;

    if (ecam_pick_kernel(h, true) == ecam_position_general) {
        t->position_at = ecam_position_at_general;
        t->lookup_at = ecam_lookup_at_general;
    } else if (h->degree == 1u) {
        t->position_at = pow2 ? ecam_position_at_linear_pow2 : ecam_position_at_linear;
        t->lookup_at = pow2 ? ecam_lookup_at_linear_pow2 : ecam_lookup_at_linear;
    } else if (h->degree == 3u) {
        t->position_at = pow2 ? ecam_position_at_cubic_pow2 : ecam_position_at_cubic;
        t->lookup_at = pow2 ? ecam_lookup_at_cubic_pow2 : ecam_lookup_at_cubic;
    } else {
        t->position_at = pow2 ? ecam_position_at_quintic_pow2 : ecam_position_at_quintic;
        t->lookup_at = pow2 ? ecam_lookup_at_quintic_pow2 : ecam_lookup_at_quintic;
    }
}

/* The net stroke N/D per period (version 2): A = floor(N / D), B = N mod D and the reciprocals
 * of step 7, and the position_outside that applies them. */
static void ecam_set_net_stroke(const ecam_header *h, ecam_table *t)
{
    const uint32_t d = h->net_den; /* >= 1: checked */
    const bool negative = (h->net_num & ECAM_SIGN_BIT64) != 0u;
    const uint64_t magnitude = negative ? (0u - h->net_num) : h->net_num; /* < 2^63 */
    uint64_t whole = magnitude / d;
    uint64_t rest = magnitude % d;

    if (negative && (rest != 0u)) { /* floor: -(q + 1) and d - r */
        whole++;
        rest = d - rest;
    }
    t->net_whole = (uint32_t)(negative ? (0u - whole) : whole); /* |A| <= 2^31: its int32 bits */
    t->net_rest = (uint32_t)rest;
    t->net_den = d;
    t->net_half = d / 2u;
    t->net_recip = UINT64_MAX / d;
    t->net_bias = ECAM_SIGN_BIT64 / d;
    t->net_bias_rest = (uint32_t)(ECAM_SIGN_BIT64 % d);
    t->period_bias = ECAM_SIGN_BIT64 / h->master_counts;
    if (magnitude != 0u) { /* checked: only periodic tables have one */
        t->periodic = (uint8_t)ECAM_WRAP_NET;
        t->position_outside = ecam_position_net_outside;
        if ((d == 1u) && (h->degree == 1u)) {
            t->position_outside = (h->step_shift >= 0) ? ecam_linear_whole_pow2 : ecam_linear_whole;
        }
    }
}

/* Precomputes the format into t (runs once, so the divisions here are fine: they produce the
 * reciprocals that keep division out of the lookup path). */
static void ecam_prepare(const uint8_t *blob, const ecam_header *h, ecam_table *t)
{
    const uint8_t *payload = &blob[ECAM_HEADER_BYTES];
    const bool pow2 = h->step_shift >= 0;
    const unsigned w = h->work_bits;
    const unsigned f = h->tau_bits;
    const unsigned out = h->degree == 1u ? f + w : w; /* <= 60 */

    *t = ecam_cleared;
    t->position = payload;
    t->slope = (h->degree >= 3u) ? &payload[(size_t)h->points * 4u] : NULL;
    t->curvature = (h->degree == 5u) ? &payload[(size_t)h->points * 8u] : NULL;
    t->master_limit = h->master_counts;
    t->tau_recip = h->tau_recip;
    t->mod_recip = UINT64_MAX / h->master_counts;
    t->half = w > 0u ? UINT64_C(1) << (w - 1u) : 0u;
    t->round = h->degree == 1u ? t->half << f : t->half;
    t->position_scale = UINT64_C(1) << (w - h->position_bits);
    t->position_wide = (w - h->position_bits > 30u) ? 1u : 0u;
    t->slope_scale = UINT64_C(1) << (w - h->slope_bits);
    t->curvature_scale = UINT64_C(1) << (w - h->curvature_bits);
    t->master_counts = h->master_counts;
    t->step_counts = h->step_counts;
    t->step_recip = pow2 ? 0u : (uint32_t)((UINT64_C(1) << 32) / h->step_counts);
    t->step_mask = pow2 ? h->step_counts - 1u : 0u;
    t->mod_offset = (uint32_t)(ECAM_SIGN_BIT64 % h->master_counts);
    t->mod_complement = h->master_counts - t->mod_offset;
    t->tau_one = UINT32_C(1) << f;
    t->intervals = h->points - 1u;
    t->end_position[0] = ecam_end_point(payload, 0u, h->position_bits);
    t->end_position[1] = ecam_end_point(payload, h->points - 1u, h->position_bits);
    t->status = ECAM_OK;
    t->degree = (uint8_t)h->degree;
    t->periodic = (uint8_t)(((h->flags & 1u) != 0u) ? ECAM_WRAP : ECAM_CLAMP);
    t->step_shift = pow2 ? (uint8_t)h->step_shift : 0u;
    t->tau_bits = (uint8_t)f;
    t->tau_lshift = (uint8_t)((32u - f) & 31u);
    t->work_bits = (uint8_t)w;
    t->out_shift = (uint8_t)out;
    t->out_mul = (out > 32u) ? (uint64_t)1u : (UINT64_C(1) << (32u - out));
    t->out_rshift = (uint8_t)(out > 32u ? out - 32u : 0u);
    t->slope_preshift = (uint8_t)h->slope_preshift;
    t->slope_out_shift = (uint8_t)(ECAM_SLOPE_FRACTION_BITS + f + w - h->slope_preshift);
    ecam_set_multipliers(h, t);
    t->position_kernel = ecam_pick_kernel(h, pow2);
    t->slope_kernel = ecam_pick_slope_kernel(h);
    t->position_outside = ecam_position_outside;
    ecam_pick_at(h, t);
    ecam_set_net_stroke(h, t);
    if (h->ramp != 0u) { /* version 3: the degree's kernels run inside the ramp's */
        t->ramp = h->ramp;
        t->ramp_slope = h->ramp << ECAM_SLOPE_FRACTION_BITS; /* |S| < 2^15: S 2^16 as int32 bits */
        t->ramp_at = t->position_at;
        t->ramp_slope_kernel = t->slope_kernel;
        t->position_kernel = ecam_position_ramp;
        t->position_outside = ecam_position_ramp;
        t->position_at = ecam_position_at_ramp;
        t->lookup_at = ecam_lookup_at_ramp;
        t->slope_kernel = ecam_slope_ramp;
    }
}

/* Every check of FORMAT.md in its order; on success the prepared table in *t. */
static ecam_status ecam_load(ecam_table *t, const uint8_t *blob, size_t len)
{
    ecam_header h;
    ecam_status status = ecam_check_envelope(blob, len);

    if (status != ECAM_OK) {
        return status;
    }
    ecam_read_header(blob, &h);
    status = ecam_check_fields(blob, &h);
    if (status != ECAM_OK) {
        return status;
    }
    if ((uint64_t)len != (uint64_t)ECAM_HEADER_BYTES + h.payload_bytes) {
        return ECAM_E_LENGTH;
    }
    if (ecam_crc32(&blob[ECAM_HEADER_BYTES], h.payload_bytes) !=
        ecam_get_u32(&blob[ECAM_OFF_PAYLOAD_CRC])) {
        return ECAM_E_PAYLOAD_CRC;
    }
    status = ecam_prove(blob, &h);
    if (status != ECAM_OK) {
        return status;
    }
    ecam_prepare(blob, &h, t);
    return ECAM_OK;
}

/* Loader entry point: the table only becomes ready on success; on failure it is not ready and
 * remembers why. */
int ecam_table_init(ecam_table *t, const uint8_t *blob, size_t len)
{
    ecam_status status = ECAM_E_NULL;

    if (t == NULL) {
        return (int)ECAM_E_NULL;
    }
    if (blob != NULL) {
        status = ecam_load(t, blob, len); /* writes *t only once every rule holds */
    }
    if (status != ECAM_OK) {
        *t = ecam_cleared;
        t->status = (int32_t)status;
    }
    return (int)status;
}

/* ------------------------------------------------------------------------------------------ */
/* Double buffer                                                                              */
/* ------------------------------------------------------------------------------------------ */

/* Both tables cleared (not ready), table 0 active. */
void ecam_pair_init(ecam_table_pair *pair)
{

    if (pair == NULL) {
        return;
    }
    pair->table[0] = ecam_cleared;
    pair->table[1] = ecam_cleared;
    pair->published = 0u;
    pair->seen = 0u;
    pair->active = &pair->table[0];
}

/* Copies src into dst member by member through a volatile lvalue, so that every store is done
 * before the (volatile) publishing store that follows it. */
static void ecam_pair_write(volatile ecam_table *dst, const ecam_table *src)
{
    unsigned k;

    dst->position_kernel = src->position_kernel;
    dst->slope_kernel = src->slope_kernel;
    dst->position_outside = src->position_outside;
    dst->position_at = src->position_at;
    dst->lookup_at = src->lookup_at;
    dst->position = src->position;
    dst->slope = src->slope;
    dst->curvature = src->curvature;
    dst->master_limit = src->master_limit;
    dst->tau_recip = src->tau_recip;
    dst->mod_recip = src->mod_recip;
    dst->half = src->half;
    dst->out_mul = src->out_mul;
    dst->period_bias = src->period_bias;
    dst->net_recip = src->net_recip;
    dst->net_bias = src->net_bias;
    dst->round = src->round;
    dst->position_scale = src->position_scale;
    dst->slope_scale = src->slope_scale;
    dst->curvature_scale = src->curvature_scale;
    dst->master_counts = src->master_counts;
    dst->step_counts = src->step_counts;
    dst->step_recip = src->step_recip;
    dst->step_mask = src->step_mask;
    dst->mod_offset = src->mod_offset;
    dst->mod_complement = src->mod_complement;
    dst->tau_one = src->tau_one;
    dst->intervals = src->intervals;
    for (k = 0u; k < 2u; k++) {
        dst->end_position[k] = src->end_position[k];
    }
    for (k = 0u; k < 14u; k++) {
        dst->multiplier[k] = src->multiplier[k];
    }
    dst->status = src->status;
    dst->net_whole = src->net_whole;
    dst->net_rest = src->net_rest;
    dst->net_den = src->net_den;
    dst->net_half = src->net_half;
    dst->net_bias_rest = src->net_bias_rest;
    dst->degree = src->degree;
    dst->periodic = src->periodic;
    dst->position_wide = src->position_wide;
    dst->step_shift = src->step_shift;
    dst->tau_bits = src->tau_bits;
    dst->tau_lshift = src->tau_lshift;
    dst->work_bits = src->work_bits;
    dst->out_shift = src->out_shift;
    dst->out_rshift = src->out_rshift;
    dst->slope_preshift = src->slope_preshift;
    dst->slope_out_shift = src->slope_out_shift;
    dst->ramp_at = src->ramp_at;
    dst->ramp_slope_kernel = src->ramp_slope_kernel;
    dst->ramp = src->ramp;
    dst->ramp_slope = src->ramp_slope;
}

/* Validates into a local table, then (only if valid and the spare is free) writes the spare and
 * publishes it with one pointer store. */
int ecam_pair_load(ecam_table_pair *pair, const uint8_t *blob, size_t len)
{
    ecam_table candidate;
    ecam_table *spare;
    int status;

    if (pair == NULL) {
        return (int)ECAM_E_NULL;
    }
    status = ecam_table_init(&candidate, blob, len);
    if (status != (int)ECAM_OK) {
        return status;
    }
    if (ecam_pair_idle(pair) == 0) {
        return (int)ECAM_E_BUSY;
    }
    spare = pair->active == &pair->table[0] ? &pair->table[1] : &pair->table[0];
    ecam_pair_write(spare, &candidate);
    ECAM_MEMORY_BARRIER();
    pair->active = spare;
    pair->published = pair->published + 1u;
    return (int)ECAM_OK;
}

/* Interrupt side: note that the latest table was seen, then return it. `published` is read
 * before `active`, and the loader stores them in the opposite order, so `seen` never claims a
 * table newer than the one returned. */
const ecam_table *ecam_pair_acquire(ecam_table_pair *pair)
{
    const uint32_t published = pair->published;
    const ecam_table *active;

    ECAM_MEMORY_BARRIER();
    active = pair->active;
    pair->seen = published;
    return active;
}

/* Main-loop side: the interrupt has acquired the table published last. */
int ecam_pair_idle(const ecam_table_pair *pair)
{
    return pair != NULL && pair->seen == pair->published;
}

/* ------------------------------------------------------------------------------------------ */
/* Expanded form (FORMAT.md "Expanded form")                                                  */
/* ------------------------------------------------------------------------------------------ */

/* ecam_poly.outside: what a master outside [0, M) takes. */
#define ECAM_POLY_WRAP 0u       /* periodic: the wrap, inline */
#define ECAM_POLY_WRAP_WHOLE 1u /* a whole net stroke per period (D = 1): the wrap and k N, inline */
#define ECAM_POLY_COLD 2u       /* the clamp, or a fractional net stroke: ecam_poly_outside */

#if ECAM_WORD_BITS == 64
/* asr(x * tau, F) on 64-bit cores: one multiply, one arithmetic shift. */
static ECAM_INLINE uint64_t ecam_poly_mulshift(const ecam_poly *p, uint64_t x, uint64_t tau)
{
    return ecam_asr(x * tau, p->tau_bits);
}

/* The int32 result of asr(z, W). */
static ECAM_INLINE int32_t ecam_poly_out(const ecam_poly *p, uint64_t z)
{
    return ecam_i32((uint32_t)ecam_asr(z, p->work_bits));
}
#else
/* asr(x * tau, F) = floor(x * (tau 2^(32-F)) / 2^32) on 32-bit cores (see ecam_mulshift). */
static ECAM_INLINE uint64_t ecam_poly_mulshift(const ecam_poly *p, uint64_t x, uint32_t y)
{
    const uint64_t low = (uint64_t)(uint32_t)x * y;
    const uint32_t x_high = (uint32_t)(x >> 32);
    const uint64_t high = (uint64_t)x_high * y + (low >> 32);
    const uint32_t correction = y & (0u - (x_high >> 31)); /* y when x < 0, else 0 */

    (void)p;
    return high - ((uint64_t)correction << 32);
}

/* The int32 result of asr(z, W) without a 64-bit shift (see ecam_out). */
static ECAM_INLINE int32_t ecam_poly_out(const ecam_poly *p, uint64_t z)
{
    const uint32_t low = (uint32_t)z;
    const uint32_t high = (uint32_t)(z >> 32);
    const uint32_t y_low = (uint32_t)p->out_mul;
    const uint32_t y_high = (uint32_t)(p->out_mul >> 32);
    const uint32_t scaled =
        (uint32_t)(((uint64_t)low * y_low) >> 32) + (high * y_low) + (low * y_high);

    return ecam_i32(ecam_asr32(scaled, p->out_rshift));
}
#endif

/* floor(2 r y / 2^32) for |r| < 2^30 and 0 <= y < 2^31: the high word of one signed product. */
static ECAM_INLINE int32_t ecam_poly_mulhi(int32_t r, int32_t y)
{
    const int64_t product = (int64_t)(r * 2) * y;

    return ecam_i32((uint32_t)((uint64_t)product >> 32));
}

/* 32-bit asr(x, s) for s <= 31 (the narrow kernels' final shift). */
static ECAM_INLINE uint32_t ecam_asr32_any(uint32_t x, unsigned s)
{
    const int32_t v = ecam_i32(x);

    return (uint32_t)(v >= 0 ? v >> s : ~(~v >> s));
}

/* Steps 2 and 3 for a master inside [0, M): the interval i, and tau in *tau. */
static ECAM_INLINE uint32_t ecam_poly_locate(const ecam_poly *p, uint32_t local, bool pow2, uint32_t *tau)
{
    uint32_t i;
    uint32_t rest;

    if (pow2) {
        *tau = local & p->step_mask;
        return local >> p->step_shift;
    }
    i = (uint32_t)(((uint64_t)local * p->step_recip) >> 32); /* see ecam_locate */
    rest = local - i * p->step_counts;
    if (rest >= p->step_counts) {
        rest -= p->step_counts;
        i++;
    }
    *tau = (uint32_t)(((uint64_t)rest * p->tau_recip) >> 32);
    return i;
}

/* Step 5 of interval i at fraction tau_in, the coefficients of step 4 read from the buffer (the
 * rounding term is in c0): one load per coefficient, one multiply-shift-add per degree. */
static ECAM_INLINE int32_t ecam_poly_eval(const ecam_poly *p, uint32_t i, uint32_t tau_in, unsigned n)
{
    const int64_t *c = &p->coefficient[(size_t)i * (n + 1u)];

    {
#if ECAM_WORD_BITS == 64
        const uint64_t tau = tau_in;
#else
        const uint32_t tau = tau_in << p->tau_lshift;
#endif
        uint64_t r = (uint64_t)c[n];

        /* written out (n is a constant here): a loop costs a counter and a compare per step */
        if (n == 5u) {
            r = (uint64_t)c[4] + ecam_poly_mulshift(p, r, tau);
            r = (uint64_t)c[3] + ecam_poly_mulshift(p, r, tau);
            r = (uint64_t)c[2] + ecam_poly_mulshift(p, r, tau);
        } else if (n == 3u) {
            r = (uint64_t)c[2] + ecam_poly_mulshift(p, r, tau);
        } else {
            /* linear: c1 alone */
        }
        if (n != 1u) {
            r = (uint64_t)c[1] + ecam_poly_mulshift(p, r, tau);
        }
        return ecam_poly_out(p, (uint64_t)c[0] + ecam_poly_mulshift(p, r, tau));
    }
}

/* Steps 2, 3 and 5 for a master inside [0, M). */
static ECAM_INLINE int32_t ecam_poly_at(const ecam_poly *p, uint32_t local, unsigned n, bool pow2)
{
    uint32_t tau_in = 0u;
    const uint32_t i = ecam_poly_locate(p, local, pow2, &tau_in);

    return ecam_poly_eval(p, i, tau_in, n);
}

/* Step 5 in 32-bit words, for a table whose Horner values all stay below 2^30 (see
 * ecam_poly_narrow): with y = tau 2^(31-F) < 2^31, asr(r tau, F) = floor(2r y / 2^32), the high
 * word of one 32x32 signed product, exactly; the final sum fits int32 and W <= 30. */
static ECAM_INLINE int32_t ecam_poly_narrow_eval(const ecam_poly *p, uint32_t i, uint32_t tau_in, unsigned n)
{
    const int64_t *c = &p->coefficient[(size_t)i * (n + 1u)];
    const int32_t y = (int32_t)(tau_in << p->narrow_lshift);
    int32_t r = (int32_t)c[n];

    if (n == 5u) {
        r = (int32_t)c[4] + ecam_poly_mulhi(r, y);
        r = (int32_t)c[3] + ecam_poly_mulhi(r, y);
        r = (int32_t)c[2] + ecam_poly_mulhi(r, y);
    } else if (n == 3u) {
        r = (int32_t)c[2] + ecam_poly_mulhi(r, y);
    } else {
        /* linear: c1 alone */
    }
    if (n != 1u) {
        r = (int32_t)c[1] + ecam_poly_mulhi(r, y);
    }
    return ecam_i32(ecam_asr32_any((uint32_t)((int32_t)c[0] + ecam_poly_mulhi(r, y)), p->work_bits));
}

static ECAM_INLINE int32_t ecam_poly_narrow_at(const ecam_poly *p, uint32_t local, unsigned n, bool pow2)
{
    uint32_t tau_in = 0u;
    const uint32_t i = ecam_poly_locate(p, local, pow2, &tau_in);

    return ecam_poly_narrow_eval(p, i, tau_in, n);
}

static ECAM_COLD int32_t ecam_poly_outside(const ecam_poly *p, int64_t m);

#if ECAM_POLY_FOLD
/*
 * Steps 1..3 for a periodic table with h = 2^k whose period M = N 2^k is not a power of two, on a
 * 32-bit core that divides in one instruction (ECAM_POLY_FOLD): i = floor(m / 2^k) mod N and
 * tau = m mod 2^k for any int64 m = hi 2^32 + lo (hi signed, lo unsigned), by two 32-bit
 * remainders instead of the table's 64-bit Barrett reduction (Cortex-M4 at -O2: SDIV, MLS, MLA,
 * UDIV, MLS and their loads, 10 instructions more than a master inside the period, where the four
 * 32x32 products of the 64-bit quotient and its corrections cost about 27; tests/test_cross_targets.py
 * counts them).
 * The algorithm: the residue of a two-word number modulo a one-word N, word by word (Knuth, TAOCP
 * vol. 2, 3rd ed., 4.3.1, exercise 16, short division), with the words cut at bit k, not 32, so
 * that the interval is the residue itself, and with the radix 2^(32-k) replaced by its residue
 * c = 2^(32-k) mod N (r 2^(32-k) + u = r c + u modulo N), so that each step is one 32-bit
 * remainder instead of a 64-by-32 division. (A 64-by-32 remainder of m by M itself, e.g. Moller
 * and Granlund's preinverted division, "Improved division by invariant integers", IEEE Trans.
 * Computers 60(2), 2011, Algorithm 4, needs a normalising shift of both words and two
 * corrections: about as many instructions as the Barrett reduction on this core.)
 * Why it is exact: floor(m / 2^k) = hi 2^(32-k) + floor(lo / 2^k) (0 <= k <= 30), and local =
 * (floor(m / 2^k) mod N) 2^k + (m mod 2^k) since M = N 2^k. With r = hi % N (C99: the sign of hi,
 * |r| < N) and B = N (N - 1), a multiple of N, x = r c + floor(lo / 2^k) + B is congruent to
 * floor(m / 2^k) modulo N and lies in [N - 1, (N - 1)(2N - 1) + 2^(32-k) - 1], which
 * ecam_poly_init requires below 2^32 (so N < 46342, and k >= 1): the uint32 sum, taken modulo
 * 2^32, is x itself, and i = x mod N. (The Cortex-M4's UDIV and SDIV take 2 to 12 cycles, by their
 * operands: Cortex-M4 Technical Reference Manual, ARM DDI 0439, 3.3.1, Table 3-1.)
 */
static ECAM_INLINE uint32_t ecam_poly_fold(const ecam_poly *p, int64_t m, uint32_t *tau)
{
    const uint32_t lo = (uint32_t)m;
    const int32_t hi = ecam_i32((uint32_t)((uint64_t)m >> 32));
    const int32_t rest = hi % (int32_t)p->fold_count;
    const uint32_t x = ((uint32_t)rest * (uint32_t)p->fold_factor) + (lo >> p->step_shift) + p->fold_bias;

    *tau = lo & p->step_mask;
    return x % (uint32_t)p->fold_count;
}
#endif

/* A master inside [0, M) straight through. Past it, the table's wrap (and a whole net stroke's
 * term, one multiply) inline, so that any int64 master costs one reduction more than the
 * period; the clamp and a fractional net stroke go through the cold function. */
static ECAM_INLINE int32_t ecam_poly_kernel_of(const ecam_poly *p, int64_t m, unsigned n, bool pow2,
                                               bool narrow)
{
    uint32_t local = (uint32_t)m;
    uint32_t term = 0u;

#if ECAM_WORD_BITS == 64
    if ((uint64_t)m >= p->master_limit) {
#else
    if ((uint64_t)m >= (uint32_t)p->master_limit) {
#endif
        const ecam_table *t = p->table;

        if (p->outside == ECAM_POLY_WRAP) {
            local = ecam_wrap(t, m);
        } else if (p->outside == ECAM_POLY_WRAP_WHOLE) {
            uint64_t turns = 0u;

            local = ecam_wrap_turns(t, m, &turns);
            term = (uint32_t)turns * t->net_whole;
        } else {
            return ecam_poly_outside(p, m);
        }
    }
    if (narrow) {
        return ecam_i32((uint32_t)ecam_poly_narrow_at(p, local, n, pow2) + term);
    }
    return ecam_i32((uint32_t)ecam_poly_at(p, local, n, pow2) + term);
}

#if ECAM_POLY_FOLD
/* The kernel of a periodic table without a net stroke, h = 2^k and M = N 2^k not a power of two,
 * on a 32-bit core with a divide instruction: a master inside [0, M) straight through, any other
 * by ecam_poly_fold, which gives the interval and tau themselves (no other case to dispatch). */
static ECAM_INLINE int32_t ecam_poly_fold_of(const ecam_poly *p, int64_t m, unsigned n, bool narrow)
{
    uint32_t tau = 0u;
    uint32_t i;

    if ((uint64_t)m < (uint32_t)p->master_limit) {
        i = ecam_poly_locate(p, (uint32_t)m, true, &tau);
    } else {
        i = ecam_poly_fold(p, m, &tau);
    }
    if (narrow) {
        return ecam_poly_narrow_eval(p, i, tau, n);
    }
    return ecam_poly_eval(p, i, tau, n);
}

static int32_t ecam_poly_fold_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_fold_of(p, m, 1u, false);
}

static int32_t ecam_poly_fold_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_fold_of(p, m, 3u, false);
}

static int32_t ecam_poly_fold_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_fold_of(p, m, 5u, false);
}

static int32_t ecam_poly_narrow_fold_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_fold_of(p, m, 1u, true);
}

static int32_t ecam_poly_narrow_fold_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_fold_of(p, m, 3u, true);
}

static int32_t ecam_poly_narrow_fold_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_fold_of(p, m, 5u, true);
}

/* The fold kernel of a degree, in 32-bit words (narrow) or not. */
static ecam_poly_kernel ecam_poly_fold_kernel(unsigned degree, bool narrow)
{
    static const ecam_poly_kernel kernels[2][3] = {
        {ecam_poly_fold_linear, ecam_poly_fold_cubic, ecam_poly_fold_quintic},
        {ecam_poly_narrow_fold_linear, ecam_poly_narrow_fold_cubic, ecam_poly_narrow_fold_quintic}};

    return kernels[narrow ? 1 : 0][degree / 2u];
}
#endif

static int32_t ecam_poly_linear_pow2(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 1u, true, false);
}

static int32_t ecam_poly_narrow_linear_pow2(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 1u, true, true);
}

static int32_t ecam_poly_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 1u, false, false);
}

static int32_t ecam_poly_narrow_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 1u, false, true);
}

static int32_t ecam_poly_cubic_pow2(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 3u, true, false);
}

static int32_t ecam_poly_narrow_cubic_pow2(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 3u, true, true);
}

static int32_t ecam_poly_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 3u, false, false);
}

static int32_t ecam_poly_narrow_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 3u, false, true);
}

static int32_t ecam_poly_quintic_pow2(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 5u, true, false);
}

static int32_t ecam_poly_narrow_quintic_pow2(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 5u, true, true);
}

static int32_t ecam_poly_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 5u, false, false);
}

static int32_t ecam_poly_narrow_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_kernel_of(p, m, 5u, false, true);
}

/* A period of M = 2^j master counts (and so h = 2^k): the wrap of any int64 master is its low j
 * bits and k = floor(m / M) its shift by j (the low word of the logical shift is that of the
 * arithmetic one for j <= 32), so no reduction at all. Without a net stroke there is no branch
 * either: a master inside the period and any other cost the same. */
static ECAM_INLINE int32_t ecam_poly_mask_of(const ecam_poly *p, int64_t m, unsigned n, bool narrow, bool net,
                                              bool ramp)
{
    uint32_t local = (uint32_t)m;
    uint32_t term = 0u;

    if (!net) {
        local &= p->master_mask;
    } else if ((uint64_t)m >= p->master_limit) { /* also every negative m; inside, as the others */
        local &= p->master_mask;
        term = (uint32_t)((uint64_t)m >> p->master_shift) * p->table->net_whole;
    } else {
        /* inside the period: k = 0 */
    }
    if (ramp) { /* version 3: step 8's S m_local (modulo 2^32, as the term) */
        term += local * p->ramp;
    }
    if (narrow) {
        return ecam_i32((uint32_t)ecam_poly_narrow_at(p, local, n, true) + term);
    }
    return ecam_i32((uint32_t)ecam_poly_at(p, local, n, true) + term);
}

static int32_t ecam_poly_mask_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 1u, false, false, false);
}

static int32_t ecam_poly_mask_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 3u, false, false, false);
}

static int32_t ecam_poly_mask_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 5u, false, false, false);
}

static int32_t ecam_poly_mask_net_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 1u, false, true, false);
}

static int32_t ecam_poly_mask_net_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 3u, false, true, false);
}

static int32_t ecam_poly_mask_net_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 5u, false, true, false);
}

static int32_t ecam_poly_narrow_mask_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 1u, true, false, false);
}

static int32_t ecam_poly_narrow_mask_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 3u, true, false, false);
}

static int32_t ecam_poly_narrow_mask_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 5u, true, false, false);
}

static int32_t ecam_poly_narrow_mask_net_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 1u, true, true, false);
}

static int32_t ecam_poly_narrow_mask_net_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 3u, true, true, false);
}

static int32_t ecam_poly_narrow_mask_net_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 5u, true, true, false);
}

static int32_t ecam_poly_mask_ramp_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 1u, false, true, true);
}

static int32_t ecam_poly_mask_ramp_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 3u, false, true, true);
}

static int32_t ecam_poly_mask_ramp_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 5u, false, true, true);
}

static int32_t ecam_poly_narrow_mask_ramp_linear(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 1u, true, true, true);
}

static int32_t ecam_poly_narrow_mask_ramp_cubic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 3u, true, true, true);
}

static int32_t ecam_poly_narrow_mask_ramp_quintic(const ecam_poly *p, int64_t m)
{
    return ecam_poly_mask_of(p, m, 5u, true, true, true);
}

/* The kernel of a table whose period is M = 2^j (ecam_poly_mask_of), by degree, word width, net
 * stroke and ramp (version 3, which has a net stroke). */
static ecam_poly_kernel ecam_poly_mask_kernel(unsigned degree, bool narrow, bool net, bool ramp)
{
    static const ecam_poly_kernel wide_ramp[3] = {ecam_poly_mask_ramp_linear, ecam_poly_mask_ramp_cubic,
                                                  ecam_poly_mask_ramp_quintic};
    static const ecam_poly_kernel thin_ramp[3] = {ecam_poly_narrow_mask_ramp_linear, ecam_poly_narrow_mask_ramp_cubic,
                                                  ecam_poly_narrow_mask_ramp_quintic};

    if (ramp) {
        return narrow ? thin_ramp[degree / 2u] : wide_ramp[degree / 2u];
    }
    static const ecam_poly_kernel wide[2][3] = {
        {ecam_poly_mask_linear, ecam_poly_mask_cubic, ecam_poly_mask_quintic},
        {ecam_poly_mask_net_linear, ecam_poly_mask_net_cubic, ecam_poly_mask_net_quintic}};
    static const ecam_poly_kernel thin[2][3] = {
        {ecam_poly_narrow_mask_linear, ecam_poly_narrow_mask_cubic, ecam_poly_narrow_mask_quintic},
        {ecam_poly_narrow_mask_net_linear, ecam_poly_narrow_mask_net_cubic, ecam_poly_narrow_mask_net_quintic}};

    if (narrow) { /* (32-bit cores only: ecam_poly_init picks no narrow kernel on 64-bit ones) */
        return thin[net ? 1 : 0][degree / 2u];
    }
    return wide[net ? 1 : 0][degree / 2u];
}

/* Step 1 past [0, M): the table's clamp, or its wrap (and step 7's term), then the kernel again
 * with the master inside the period. */
static ECAM_COLD int32_t ecam_poly_outside(const ecam_poly *p, int64_t m)
{
    const ecam_table *t = p->table;
    uint64_t turns = 0u;
    uint32_t local;
    uint32_t term = 0u;

    if (t->periodic == ECAM_CLAMP) {
        return m < 0 ? t->end_position[0] : t->end_position[1];
    }
    if (t->periodic == ECAM_WRAP_NET) {
        local = ecam_wrap_turns(t, m, &turns);
        term = ecam_net_term(t, turns);
    } else {
        local = ecam_wrap(t, m);
    }
    return ecam_i32((uint32_t)p->kernel(p, (int64_t)local) + term);
}

/* A version-3 table's kernel: the ramp's wrap and term (ecam_ramp_wrap), then the degree's
 * kernel on a master inside [0, M). */
static int32_t ecam_poly_ramp(const ecam_poly *p, int64_t m)
{
    uint32_t term = 0u;
    const uint32_t local = ecam_ramp_wrap(p->table, m, &term);

    return ecam_i32((uint32_t)p->ramp_kernel(p, (int64_t)local) + term);
}

/* |x| of an int64 below 2^63 in magnitude, as uint64 (the proof keeps c_k far from -2^63). */
static uint64_t ecam_magnitude(int64_t x)
{
    return (x < 0) ? (0u - (uint64_t)x) : (uint64_t)x;
}

/* True when every interval's Horner values fit the narrow kernels (FORMAT.md "Expanded form"):
 * with r_n = |c_n|, r_k = |c_k| + r_(k+1) + 1, every r_k < 2^30, |c0| + r_1 + 1 < 2^31, W <= 30. */
static bool ecam_poly_narrow(const int64_t *c, const ecam_table *t)
{
    const uint64_t limit = UINT64_C(1) << 30;
    const size_t words = (size_t)t->degree + 1u;
    uint32_t i;
    unsigned k;

    if (t->work_bits > 30u) {
        return false;
    }
    for (i = 0u; i < t->intervals; i++) {
        const int64_t *row = &c[(size_t)i * words];
        uint64_t r = ecam_magnitude(row[t->degree]);

        if (r >= limit) {
            return false;
        }
        for (k = (unsigned)t->degree - 1u; k >= 1u; k--) {
            r += ecam_magnitude(row[k]) + 1u; /* each term below 2^63: no wrap */
            if (r >= limit) {
                return false;
            }
        }
        if (ecam_magnitude(row[0]) + r + 1u >= (UINT64_C(1) << 31)) {
            return false;
        }
    }
    return true;
}

/* h = 2^k, M = N 2^k not a power of two, a periodic table without a net stroke, and a core with
 * a divide instruction: the fold kernels (ecam_poly_fold), when N keeps its sum below 2^32. */
static void ecam_poly_pick_fold(ecam_poly *p, const ecam_table *t, bool pow2)
{
#if ECAM_POLY_FOLD
    if (pow2 && (p->outside == (uint8_t)ECAM_POLY_WRAP) && ((t->master_counts & p->master_mask) != 0u)) {
        const uint64_t n = t->intervals;                              /* <= 2^31: no product wraps */
        const uint64_t power = UINT64_C(1) << (32u - t->step_shift); /* 2^(32-k) */
        const bool narrow = (p->kernel == ecam_poly_narrow_linear_pow2) || (p->kernel == ecam_poly_narrow_cubic_pow2) ||
                            (p->kernel == ecam_poly_narrow_quintic_pow2);

        if ((((n - 1u) * ((2u * n) - 1u)) + power) <= (UINT64_C(1) << 32)) { /* so n < 46342 */
            p->fold_count = (uint16_t)n;
            p->fold_factor = (uint16_t)(power % n);
            p->fold_bias = (uint32_t)(n * (n - 1u));
            p->kernel = ecam_poly_fold_kernel(t->degree, narrow);
        }
    }
#else
    (void)p;
    (void)t;
    (void)pow2;
#endif
}

size_t ecam_poly_bytes(const ecam_table *t)
{
    size_t words;

    if (ecam_table_ready(t) == 0) {
        return 0u;
    }
    words = (size_t)t->degree + 1u;
    if ((size_t)t->intervals > (SIZE_MAX / sizeof(int64_t)) / words) {
        return 0u; /* past this core's address space */
    }
    return (size_t)t->intervals * words * sizeof(int64_t);
}

int ecam_poly_init(ecam_poly *p, const ecam_table *t, int64_t *buffer, size_t buffer_bytes)
{
    static const ecam_poly cleared;
    const size_t need = ecam_poly_bytes(t);
    const bool pow2 = (t != NULL) && ecam_pow2(t);
    uint32_t i;
    unsigned k;

    if (p == NULL) {
        return (int)ECAM_E_NULL;
    }
    *p = cleared;
    if (t == NULL || buffer == NULL) {
        p->status = (int32_t)ECAM_E_NULL;
        return (int)ECAM_E_NULL;
    }
    if (ecam_table_ready(t) == 0) {
        p->status = (int32_t)ecam_table_status(t);
        return (int)p->status;
    }
    if (need == 0u || buffer_bytes < need) {
        p->status = (int32_t)ECAM_E_BUFFER;
        return (int)ECAM_E_BUFFER;
    }
    /* c0 = Y0 2^(W-Qy) + half (the final rounding term folded in), then c1 .. cn of step 4;
     * the loader's proof keeps every value and sum of the lookup inside int64. */
    for (i = 0u; i < t->intervals; i++) {
        const size_t at = (size_t)i * 4u;
        int64_t *c = &buffer[(size_t)i * ((size_t)t->degree + 1u)];

        c[0] = ecam_i64(ecam_scaled_any(&t->position[at], t->position_scale) + t->half);
        for (k = 1u; k <= t->degree; k++) {
            c[k] = ecam_i64(ecam_coefficient(t, at, k));
        }
    }
    p->coefficient = buffer;
    p->table = t;
    p->master_limit = t->master_limit;
    p->tau_recip = t->tau_recip;
    p->out_mul = (t->work_bits > 32u) ? (uint64_t)1u : (UINT64_C(1) << (32u - t->work_bits));
    p->step_counts = t->step_counts;
    p->step_recip = t->step_recip;
    p->step_mask = t->step_mask;
    p->status = (int32_t)ECAM_OK;
    p->degree = t->degree;
    p->step_shift = t->step_shift;
    p->tau_bits = t->tau_bits;
    p->tau_lshift = t->tau_lshift;
    p->work_bits = t->work_bits;
    p->out_rshift = (uint8_t)((t->work_bits > 32u) ? (unsigned)t->work_bits - 32u : 0u);
    p->outside = (uint8_t)ECAM_POLY_COLD;
    if (t->periodic == ECAM_WRAP) {
        p->outside = (uint8_t)ECAM_POLY_WRAP;
    } else if ((t->periodic == ECAM_WRAP_NET) && (t->net_rest == 0u)) {
        p->outside = (uint8_t)ECAM_POLY_WRAP_WHOLE;
    } else {
        /* the clamp, or a fractional net stroke */
    }
    p->narrow_lshift = (uint8_t)(31u - t->tau_bits);
    /* 64-bit cores: the 64-bit kernels are as short (one multiply and one shift per degree) */
    if ((ECAM_WORD_BITS != 64) && ecam_poly_narrow(buffer, t) && (p->narrow_lshift >= 1u)) {
        if (t->degree == 1u) {
            p->kernel = pow2 ? ecam_poly_narrow_linear_pow2 : ecam_poly_narrow_linear;
        } else if (t->degree == 3u) {
            p->kernel = pow2 ? ecam_poly_narrow_cubic_pow2 : ecam_poly_narrow_cubic;
        } else {
            p->kernel = pow2 ? ecam_poly_narrow_quintic_pow2 : ecam_poly_narrow_quintic;
        }
    } else if (t->degree == 1u) {
        p->kernel = pow2 ? ecam_poly_linear_pow2 : ecam_poly_linear;
    } else if (t->degree == 3u) {
        p->kernel = pow2 ? ecam_poly_cubic_pow2 : ecam_poly_cubic;
    } else {
        p->kernel = pow2 ? ecam_poly_quintic_pow2 : ecam_poly_quintic;
    }
    p->master_mask = t->master_counts - 1u;
    p->ramp = t->ramp;
    if (pow2 && ((t->master_counts & p->master_mask) == 0u) &&
        (p->outside != (uint8_t)ECAM_POLY_COLD)) { /* M = 2^j, no clamp, no fractional net stroke */
        const bool narrow = (p->kernel == ecam_poly_narrow_linear_pow2) || (p->kernel == ecam_poly_narrow_cubic_pow2) ||
                            (p->kernel == ecam_poly_narrow_quintic_pow2);

        while ((UINT32_C(1) << p->master_shift) != t->master_counts) {
            p->master_shift++;
        }
        p->kernel = ecam_poly_mask_kernel(t->degree, narrow, p->outside == (uint8_t)ECAM_POLY_WRAP_WHOLE,
                                          t->ramp != 0u);
    } else if (t->ramp != 0u) { /* version 3: the kernel runs inside the ramp's */
        p->ramp_kernel = p->kernel;
        p->kernel = ecam_poly_ramp;
    } else {
        ecam_poly_pick_fold(p, t, pow2);
    }
    return (int)ECAM_OK;
}

int32_t ecam_poly_position(const ecam_poly *p, int64_t master_counts)
{
    if (p == NULL || p->kernel == NULL) {
        return ECAM_INVALID;
    }
    return p->kernel(p, master_counts);
}

/* ------------------------------------------------------------------------------------------ */
/* Status names                                                                               */
/* ------------------------------------------------------------------------------------------ */

/* Names indexed by -status (0 .. 36). */

/* Stable identifiers for logs and test drivers; unknown codes get a generic name. */
const char *ecam_status_name(int status)
{
    static const char *const ecam_status_names[] = {
        "ECAM_OK",
        "ECAM_E_SHORT",
        "ECAM_E_MAGIC",
        "ECAM_E_VERSION",
        "ECAM_E_HEADER_SIZE",
        "ECAM_E_HEADER_CRC",
        "ECAM_E_FIELD",
        "ECAM_E_LENGTH",
        "ECAM_E_PAYLOAD_CRC",
        "ECAM_E_NULL",
        "ECAM_E_DEGREE",
        "ECAM_E_FLAGS",
        "ECAM_E_RESERVED",
        "ECAM_E_POINTS",
        "ECAM_E_MASTER_COUNTS",
        "ECAM_E_STEP_COUNTS",
        "ECAM_E_STEP_SHIFT",
        "ECAM_E_TAU_BITS",
        "ECAM_E_TAU_RECIP",
        "ECAM_E_POSITION_BITS",
        "ECAM_E_WORK_BITS",
        "ECAM_E_SLOPE_BITS",
        "ECAM_E_CURVATURE_BITS",
        "ECAM_E_SLOPE_PRESHIFT",
        "ECAM_E_PAYLOAD_BYTES",
        "ECAM_E_POINT_RANGE",
        "ECAM_E_HORNER_RANGE",
        "ECAM_E_SUM_RANGE",
        "ECAM_E_POSITION_RANGE",
        "ECAM_E_SLOPE_HORNER_RANGE",
        "ECAM_E_SLOPE_PRODUCT",
        "ECAM_E_SLOPE_RANGE",
        "ECAM_E_UNINITIALISED",
        "ECAM_E_BUSY",
        "ECAM_E_NET_STROKE",
        "ECAM_E_BUFFER",
        "ECAM_E_RAMP"};

    const size_t names = sizeof ecam_status_names / sizeof ecam_status_names[0];
    const int count = (int)names;

    if (status > 0 || status <= -count) {
        return "ECAM_E_UNKNOWN";
    }
    return ecam_status_names[-status];
}
