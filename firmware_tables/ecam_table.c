/*
 * ecam_table.c - C99 reference runtime for ecam cam tables, format version 1 (see FORMAT.md).
 *
 * Arithmetic convention of the lookup path: FORMAT.md specifies signed 64-bit intermediates, and
 * the compiler certifies that none of them leaves the int64 range for the tables it writes. This
 * file carries those intermediates as uint64_t two's-complement bit patterns: addition,
 * subtraction, multiplication and left shifts are then exactly the signed results mod 2^64 (equal
 * to the signed results whenever they are in range), and ecam_asr reads the sign bit itself.
 * So a certified table gives the spec's values bit for bit, and a blob that passes every loader
 * check but was never certified can at worst give wrong numbers, never undefined behaviour.
 */
#include "ecam_table.h"

/* Byte offsets of the header fields, from the table in FORMAT.md. */
enum {
    ECAM_OFF_MAGIC = 0,
    ECAM_OFF_VERSION = 4,
    ECAM_OFF_HEADER_BYTES = 6,
    ECAM_OFF_DEGREE = 8,
    ECAM_OFF_FLAGS = 9,
    ECAM_OFF_STEP_SHIFT = 10,
    ECAM_OFF_TAU_BITS = 11,
    ECAM_OFF_WORK_BITS = 12,
    ECAM_OFF_SLOPE_BITS = 13,
    ECAM_OFF_CURVATURE_BITS = 14,
    ECAM_OFF_SLOPE_PRESHIFT = 15,
    ECAM_OFF_POINTS = 16,
    ECAM_OFF_MASTER_COUNTS = 20,
    ECAM_OFF_STEP_COUNTS = 24,
    ECAM_OFF_POSITION_BITS = 28,
    ECAM_OFF_RESERVED_A = 29,
    ECAM_OFF_TAU_RECIP = 32,
    ECAM_OFF_PAYLOAD_BYTES = 40,
    ECAM_OFF_PAYLOAD_CRC = 44,
    ECAM_OFF_RESERVED_B = 48,
    ECAM_OFF_HEADER_CRC = 60
};

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

/* ------------------------------------------------------------------------------------------ */
/* Byte access and integer helpers                                                            */
/* ------------------------------------------------------------------------------------------ */

/* Little-endian u16 read that works at any alignment and on any host byte order. */
static uint32_t ecam_get_u16(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8);
}

/* Little-endian u32 read that works at any alignment and on any host byte order. */
static uint32_t ecam_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

/* Little-endian u64 read (tau_recip) that works at any alignment and byte order. */
static uint64_t ecam_get_u64(const uint8_t *p)
{
    return (uint64_t)ecam_get_u32(p) | ((uint64_t)ecam_get_u32(p + 4) << 32);
}

/* The i8 step_shift byte as an int, without relying on implementation-defined conversions. */
static int ecam_get_i8(const uint8_t *p)
{
    return p[0] < 128u ? (int)p[0] : (int)p[0] - 256;
}

/* Bits of a stored int32 to its value, portably (a plain cast is implementation-defined). */
static int32_t ecam_i32_from_bits(uint32_t u)
{
    if (u <= (uint32_t)INT32_MAX) {
        return (int32_t)u;
    }
    return (int32_t)(u - UINT32_C(0x80000000)) - INT32_MAX - 1;
}

/* Sign-extends the bits of a stored int32 into the uint64 two's-complement working word. */
static uint64_t ecam_sext32(uint32_t u)
{
    return (uint64_t)u - ((uint64_t)(u & UINT32_C(0x80000000)) << 1);
}

/* Payload element i of one array, sign-extended into the working word. */
static uint64_t ecam_payload_word(const uint8_t *array, uint32_t i)
{
    return ecam_sext32(ecam_get_u32(array + (size_t)i * 4u));
}

/* FORMAT.md asr(x, s) = floor(x / 2^s) on a two's-complement word: the spec's
 * x >= 0 ? x >> s : ~(~x >> s), done on unsigned bits so no signed shift is involved. A valid
 * header allows P up to 16 + 30 + 40 = 86, and a C shift by 64 or more is undefined, so such
 * counts get the exact floor directly: 0 or -1. */
static uint64_t ecam_asr(uint64_t x, unsigned s)
{
    const uint64_t fill = (x & ECAM_SIGN_BIT64) ? UINT64_MAX : 0u;

    if (s > ECAM_MAX_SHIFT) {
        return fill;
    }
    return fill ^ ((fill ^ x) >> s);
}

/* Full 64x64 -> 128-bit product from 32-bit limbs, since C99 has no wider integer type;
 * Barrett reduction needs the high half and the tau_recip check needs both. */
static void ecam_mul_64x64(uint64_t a, uint64_t b, uint64_t *hi, uint64_t *lo)
{
    const uint64_t mask = UINT64_C(0xFFFFFFFF);
    const uint64_t p0 = (a & mask) * (b & mask);
    const uint64_t p1 = (a & mask) * (b >> 32);
    const uint64_t p2 = (a >> 32) * (b & mask);
    const uint64_t p3 = (a >> 32) * (b >> 32);
    /* Three terms below 2^32 each: mid < 3 * 2^32, no overflow. */
    const uint64_t mid = (p0 >> 32) + (p1 & mask) + (p2 & mask);

    *lo = (mid << 32) | (p0 & mask);
    *hi = p3 + (p1 >> 32) + (p2 >> 32) + (mid >> 32);
}

/* ------------------------------------------------------------------------------------------ */
/* CRC-32                                                                                     */
/* ------------------------------------------------------------------------------------------ */

/* Nibble table of the reflected IEEE polynomial 0xEDB88320: 64 bytes of flash instead of 1 KiB. */
static const uint32_t ecam_crc_nibble[16] = {
    0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu, 0x76DC4190u, 0x6B6B51F4u,
    0x4DB26158u, 0x5005713Cu, 0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu,
    0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu};

/* Same value as zlib.crc32, so blobs written by Python tools verify here. */
uint32_t ecam_crc32(const uint8_t *data, size_t len)
{
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
/* Divide-free reductions                                                                     */
/* ------------------------------------------------------------------------------------------ */

/*
 * u mod M for any u < 2^64 by Barrett reduction, with mu = floor((2^64 - 1) / M), 2 <= M <= 2^31.
 * One correction suffices. Let q = floor(u * mu / 2^64), the high half of u * mu.
 *  - q <= u / M, because mu <= (2^64 - 1) / M < 2^64 / M; hence q <= floor(u / M) and r >= 0.
 *  - mu >= ((2^64 - 1) - (M - 1)) / M = 2^64 / M - 1, so u * mu / 2^64 >= u / M - u / 2^64
 *    > u / M - 1, hence q > u / M - 2, i.e. q >= floor(u / M) - 1.
 * So r = u - q * M lies in [0, 2M) and a single conditional subtraction lands it in [0, M).
 */
static uint32_t ecam_mod_u64(uint64_t u, uint64_t mu, uint32_t modulus)
{
    uint64_t q;
    uint64_t unused_lo;
    uint64_t r;

    ecam_mul_64x64(u, mu, &q, &unused_lo);
    (void)unused_lo;
    r = u - q * modulus;
    if (r >= modulus) {
        r -= modulus;
    }
    return (uint32_t)r;
}

/*
 * Periodic wrap of FORMAT.md step 1: floor modulo m mod M for every int64 m (INT64_MIN included).
 * Flipping the sign bit maps m to u = m + 2^63 in [0, 2^64), and
 * m mod M = (u mod M - 2^63 mod M) mod M, where the outer mod is one conditional add because
 * both terms are already in [0, M).
 */
static uint32_t ecam_floor_mod(const ecam_table *t, int64_t m)
{
    const uint64_t u = (uint64_t)m ^ ECAM_SIGN_BIT64;
    const uint32_t r = ecam_mod_u64(u, t->mod_recip, t->master_counts);

    if (r >= t->mod_offset) {
        return r - t->mod_offset;
    }
    return r + (t->master_counts - t->mod_offset);
}

/*
 * FORMAT.md step 2: interval index i = floor(m_local / h) and offset t = m_local - i * h.
 * For h = 2^k this is a shift and a mask. Otherwise g = floor(2^32 / h) (h >= 3, so g < 2^32)
 * and the estimate i' = floor(m_local * g / 2^32) needs at most one correction:
 *  - g <= 2^32 / h gives i' <= m_local / h, so i' <= i;
 *  - g > 2^32 / h - 1 gives m_local * g / 2^32 > m_local / h - m_local / 2^32 > m_local / h - 1/2
 *    (m_local < M <= 2^31), so i' >= i - 1.
 * m_local * g < 2^31 * 2^32 fits in uint64, and i' * h <= m_local < 2^31 fits in uint32.
 */
static uint32_t ecam_interval(const ecam_table *t, uint32_t m_local, uint32_t *offset)
{
    uint32_t i;
    uint32_t rest;

    if (t->step_shift >= 0) {
        i = m_local >> t->step_shift;
        rest = m_local & (t->step_counts - 1u);
    } else {
        i = (uint32_t)(((uint64_t)m_local * t->step_recip) >> 32);
        rest = m_local - i * t->step_counts;
        if (rest >= t->step_counts) {
            rest -= t->step_counts;
            i++;
        }
    }
    *offset = rest;
    return i;
}

/* ------------------------------------------------------------------------------------------ */
/* Lookup (FORMAT.md steps 3..6)                                                              */
/* ------------------------------------------------------------------------------------------ */

/*
 * Step 3: tau = floor(t * R / 2^32). t < h and R * h < 2^(32+F) + h <= 2^62 + 2^30, so the
 * product fits in 63 bits. tau < 2^F holds because h <= 2^F and h <= 2^30 give
 * h * (h - 1) < 2^(32+F), which bounds (h - 1) * R / 2^32 below 2^F.
 */
static uint64_t ecam_tau(const ecam_table *t, uint32_t offset)
{
    return ((uint64_t)offset * t->tau_recip) >> 32;
}

/*
 * Step 4: the Hermite coefficients c[1..n] of interval i in Q(W) slave counts. Returns n.
 * Constant multiples are written as multiplications on the working word; the left shifts are
 * unsigned, so they are multiplications by 2^s mod 2^64 (W >= Qy, Qa, Qb: checked by the loader).
 */
static unsigned ecam_coefficients(const ecam_table *t, uint32_t i, uint64_t c[6])
{
    const unsigned w = t->work_bits;
    const uint64_t d = (ecam_payload_word(t->position, i + 1u) -
                        ecam_payload_word(t->position, i)) << (w - t->position_bits);
    uint64_t a0;
    uint64_t a1;
    uint64_t b0;
    uint64_t b1;

    if (t->degree == 1u) {
        c[1] = d;
        return 1u;
    }
    a0 = ecam_payload_word(t->slope, i) << (w - t->slope_bits);
    a1 = ecam_payload_word(t->slope, i + 1u) << (w - t->slope_bits);
    if (t->degree == 3u) {
        c[1] = a0;
        c[2] = 3u * d - 2u * a0 - a1;
        c[3] = a0 + a1 - 2u * d;
        return 3u;
    }
    b0 = ecam_payload_word(t->curvature, i) << (w - t->curvature_bits);
    b1 = ecam_payload_word(t->curvature, i + 1u) << (w - t->curvature_bits);
    c[1] = a0;
    c[2] = b0;
    c[3] = 10u * d - 6u * a0 - 4u * a1 - 3u * b0 + b1;
    c[4] = 8u * a0 + 7u * a1 + 3u * b0 - 15u * d - 2u * b1;
    c[5] = 6u * d - 3u * a0 - 3u * a1 - b0 + b1;
    return 5u;
}

/* Step 5: Horner in Q(W) with flooring inner shifts, then the stored point (Q(Qy) raised to
 * Q(W)) is added and one round-half-up shift by W brings the sum to whole counts. */
static int32_t ecam_eval_position(const ecam_table *t, uint64_t y0, const uint64_t c[6],
                                  unsigned n, uint64_t tau)
{
    const unsigned f = t->tau_bits;
    const unsigned w = t->work_bits; /* <= 40 */
    const uint64_t half = w > 0u ? UINT64_C(1) << (w - 1u) : 0u;
    uint64_t r = c[n];
    unsigned k;

    for (k = n - 1u; k >= 1u; k--) {
        r = c[k] + ecam_asr(r * tau, f);
    }
    r = (y0 << (w - t->position_bits)) + ecam_asr(r * tau, f) + half;
    return ecam_i32_from_bits((uint32_t)ecam_asr(r, w));
}

/* Step 6: Horner of the derivative, then the reciprocal multiply that turns "per step" into
 * Q16 "per master count" without a division. */
static int32_t ecam_eval_slope(const ecam_table *t, const uint64_t c[6], unsigned n, uint64_t tau)
{
    const unsigned f = t->tau_bits;
    const unsigned p = t->slope_preshift;
    const unsigned out_shift = ECAM_SLOPE_FRACTION_BITS + f + t->work_bits - p; /* 0..63 */
    /* p itself may reach 86; ecam_asr gives the exact floor for counts past 63. */
    uint64_t q = n * c[n];
    unsigned k;

    for (k = n - 1u; k >= 1u; k--) {
        q = k * c[k] + ecam_asr(q * tau, f);
    }
    return ecam_i32_from_bits((uint32_t)ecam_asr(ecam_asr(q, p) * t->tau_recip, out_shift));
}

/* Clamp of FORMAT.md step 1 for non-periodic tables: the end point, rounded half up from
 * Q(Qy) to whole counts, holds motionless. |stored| <= 2^31 and halfy <= 2^29, so the
 * result always fits int32. */
static int32_t ecam_end_position(const ecam_table *t, int64_t master_counts)
{
    const uint32_t i = master_counts < 0 ? 0u : t->intervals;
    const unsigned qy = t->position_bits;
    const uint64_t halfy = qy > 0u ? UINT64_C(1) << (qy - 1u) : 0u;

    return ecam_i32_from_bits(
        (uint32_t)ecam_asr(ecam_payload_word(t->position, i) + halfy, qy));
}

/* Steps 1..6 on an initialised table; outputs that are NULL are neither computed nor written. */
static void ecam_evaluate(const ecam_table *t, int64_t master_counts, int32_t *position,
                          int32_t *slope)
{
    uint32_t m_local;
    uint32_t offset;
    uint32_t i;
    uint64_t c[6];
    uint64_t tau;
    unsigned n;

    if (!t->periodic && (master_counts < 0 || master_counts >= (int64_t)t->master_counts)) {
        if (position != NULL) {
            *position = ecam_end_position(t, master_counts);
        }
        if (slope != NULL) {
            *slope = 0;
        }
        return;
    }
    m_local = t->periodic ? ecam_floor_mod(t, master_counts) : (uint32_t)master_counts;
    i = ecam_interval(t, m_local, &offset); /* i < N because m_local < M = N * h */
    tau = ecam_tau(t, offset);
    n = ecam_coefficients(t, i, c);
    if (position != NULL) {
        *position = ecam_eval_position(t, ecam_payload_word(t->position, i), c, n, tau);
    }
    if (slope != NULL) {
        *slope = ecam_eval_slope(t, c, n, tau);
    }
}

/* The hot path: both outputs of one master position, sharing range, interval and coefficients.
 * A table that was never successfully initialised answers 0, 0 instead of faulting. */
void ecam_table_lookup(const ecam_table *t, int64_t master_counts, int32_t *position,
                       int32_t *slope)
{
    if (t != NULL && t->position != NULL) {
        ecam_evaluate(t, master_counts, position, slope);
        return;
    }
    if (position != NULL) {
        *position = 0;
    }
    if (slope != NULL) {
        *slope = 0;
    }
}

/* Convenience for callers that only need the commanded slave position. */
int32_t ecam_table_position(const ecam_table *t, int64_t master_counts)
{
    int32_t position;

    ecam_table_lookup(t, master_counts, &position, NULL);
    return position;
}

/* Convenience for callers that only need the velocity feed-forward ratio. */
int32_t ecam_table_slope(const ecam_table *t, int64_t master_counts)
{
    int32_t slope;

    ecam_table_lookup(t, master_counts, NULL, &slope);
    return slope;
}

/* ------------------------------------------------------------------------------------------ */
/* Loader                                                                                     */
/* ------------------------------------------------------------------------------------------ */

/* Number of int32 arrays in the payload (V in FORMAT.md) for a supported degree, else 0. */
static unsigned ecam_arrays_for_degree(unsigned degree)
{
    switch (degree) {
    case 1u:
        return 1u;
    case 3u:
        return 2u;
    case 5u:
        return 3u;
    default:
        return 0u;
    }
}

/* The checks FORMAT.md lists before the field rules, in the order it lists them. */
static int ecam_check_envelope(const uint8_t *blob, size_t len)
{
    if (len < ECAM_HEADER_BYTES) {
        return ECAM_E_SHORT;
    }
    if (blob[0] != 'E' || blob[1] != 'C' || blob[2] != 'A' || blob[3] != 'M') {
        return ECAM_E_MAGIC;
    }
    if (ecam_get_u16(blob + ECAM_OFF_VERSION) != ECAM_FORMAT_VERSION) {
        return ECAM_E_VERSION;
    }
    if (ecam_get_u16(blob + ECAM_OFF_HEADER_BYTES) != ECAM_HEADER_BYTES) {
        return ECAM_E_HEADER_SIZE;
    }
    if (ecam_crc32(blob, ECAM_OFF_HEADER_CRC) != ecam_get_u32(blob + ECAM_OFF_HEADER_CRC)) {
        return ECAM_E_HEADER_CRC;
    }
    return ECAM_OK;
}

/* Reserved space must be zero so that a future version can use it without ambiguity. */
static int ecam_reserved_ok(const uint8_t *blob)
{
    unsigned n;

    for (n = ECAM_OFF_RESERVED_A; n < ECAM_OFF_TAU_RECIP; n++) {
        if (blob[n] != 0u) {
            return 0;
        }
    }
    for (n = ECAM_OFF_RESERVED_B; n < ECAM_OFF_HEADER_CRC; n++) {
        if (blob[n] != 0u) {
            return 0;
        }
    }
    return 1;
}

/* Rules of degree, Qy, W, Qa, Qb and P (F is checked with the geometry). */
static int ecam_format_bits_ok(const ecam_table *t)
{
    const unsigned w = t->work_bits;
    const unsigned scaled = ECAM_SLOPE_FRACTION_BITS + t->tau_bits + w;

    if (ecam_arrays_for_degree(t->degree) == 0u) {
        return 0;
    }
    if (t->position_bits > ECAM_MAX_POSITION_BITS) {
        return 0;
    }
    if (w > ECAM_MAX_WORK_BITS || w < t->position_bits) {
        return 0;
    }
    if (t->slope_bits > w || t->curvature_bits > w) {
        return 0;
    }
    if (t->degree == 1u && (w != t->position_bits || t->slope_bits != 0u)) {
        return 0;
    }
    if (t->degree != 5u && t->curvature_bits != 0u) {
        return 0;
    }
    /* 0 <= P holds by type; 16 + F + W - P must lie in 0..63. */
    return t->slope_preshift <= scaled && scaled - t->slope_preshift <= ECAM_MAX_SHIFT;
}

/* F rule (ceil(log2 h) <= F <= 30, F = k for h = 2^k) and step_shift rule together. */
static int ecam_step_bits_ok(uint32_t h, int step_shift, unsigned f)
{
    if (f > ECAM_MAX_TAU_BITS || h > (UINT32_C(1) << f)) {
        return 0;
    }
    if ((h & (h - 1u)) == 0u) {
        return step_shift == (int)f && (UINT32_C(1) << f) == h;
    }
    return step_shift == -1;
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

/* Points, M, h, F, step_shift, tau_recip and payload_bytes, which constrain one another. */
static int ecam_geometry_ok(const uint8_t *blob, const ecam_table *t)
{
    const uint32_t points = ecam_get_u32(blob + ECAM_OFF_POINTS);
    const uint32_t m = t->master_counts;
    const uint32_t h = t->step_counts;
    const uint64_t payload_bytes = ecam_get_u32(blob + ECAM_OFF_PAYLOAD_BYTES);

    if (points < 2u || m < ECAM_MIN_MASTER_COUNTS || m > ECAM_MAX_MASTER_COUNTS) {
        return 0;
    }
    if (h < 1u || h > ECAM_MAX_STEP_COUNTS || (uint64_t)(points - 1u) * h != m) {
        return 0;
    }
    if (!ecam_step_bits_ok(h, t->step_shift, t->tau_bits)) {
        return 0;
    }
    if (!ecam_tau_recip_ok(t->tau_recip, h, t->tau_bits)) {
        return 0;
    }
    return payload_bytes == (uint64_t)points * 4u * ecam_arrays_for_degree(t->degree);
}

/* Copies the header fields into t (no checks yet). */
static void ecam_read_fields(const uint8_t *blob, ecam_table *t)
{
    t->degree = blob[ECAM_OFF_DEGREE];
    t->periodic = (uint8_t)(blob[ECAM_OFF_FLAGS] & 1u);
    t->step_shift = (int8_t)ecam_get_i8(blob + ECAM_OFF_STEP_SHIFT);
    t->tau_bits = blob[ECAM_OFF_TAU_BITS];
    t->work_bits = blob[ECAM_OFF_WORK_BITS];
    t->slope_bits = blob[ECAM_OFF_SLOPE_BITS];
    t->curvature_bits = blob[ECAM_OFF_CURVATURE_BITS];
    t->slope_preshift = blob[ECAM_OFF_SLOPE_PRESHIFT];
    t->position_bits = blob[ECAM_OFF_POSITION_BITS];
    t->master_counts = ecam_get_u32(blob + ECAM_OFF_MASTER_COUNTS);
    t->step_counts = ecam_get_u32(blob + ECAM_OFF_STEP_COUNTS);
    t->tau_recip = ecam_get_u64(blob + ECAM_OFF_TAU_RECIP);
}

/* Every field rule of FORMAT.md, on a header whose CRC already matched. */
static int ecam_fields_ok(const uint8_t *blob, const ecam_table *t)
{
    return (blob[ECAM_OFF_FLAGS] & ~1u) == 0u && ecam_reserved_ok(blob) &&
           ecam_format_bits_ok(t) && ecam_geometry_ok(blob, t);
}

/* Derived constants and payload pointers; runs once, so the divisions here are acceptable
 * (they produce the reciprocals that keep division out of the lookup path). */
static void ecam_prepare(const uint8_t *blob, ecam_table *t)
{
    const uint32_t points = ecam_get_u32(blob + ECAM_OFF_POINTS);
    const uint8_t *payload = blob + ECAM_HEADER_BYTES;

    t->intervals = points - 1u;
    t->position = payload;
    t->slope = t->degree >= 3u ? payload + (size_t)points * 4u : NULL;
    t->curvature = t->degree == 5u ? payload + (size_t)points * 8u : NULL;
    t->mod_recip = UINT64_MAX / t->master_counts;
    t->mod_offset = ecam_mod_u64(ECAM_SIGN_BIT64, t->mod_recip, t->master_counts);
    t->step_recip = t->step_shift >= 0 ? 0u : (uint32_t)((UINT64_C(1) << 32) / t->step_counts);
}

/* Loader: every check of FORMAT.md, in its order; the table only becomes usable on success. */
int ecam_table_init(ecam_table *t, const uint8_t *blob, size_t len)
{
    static const ecam_table cleared; /* all zero: lookups answer 0, 0 */
    ecam_table candidate = cleared;
    uint32_t payload_bytes;
    int status;

    if (t == NULL) {
        return ECAM_E_NULL;
    }
    *t = cleared;
    if (blob == NULL) {
        return ECAM_E_NULL;
    }
    status = ecam_check_envelope(blob, len);
    if (status != ECAM_OK) {
        return status;
    }
    ecam_read_fields(blob, &candidate);
    if (!ecam_fields_ok(blob, &candidate)) {
        return ECAM_E_FIELD;
    }
    payload_bytes = ecam_get_u32(blob + ECAM_OFF_PAYLOAD_BYTES);
    if ((uint64_t)len != (uint64_t)ECAM_HEADER_BYTES + payload_bytes) {
        return ECAM_E_LENGTH;
    }
    if (ecam_crc32(blob + ECAM_HEADER_BYTES, payload_bytes) !=
        ecam_get_u32(blob + ECAM_OFF_PAYLOAD_CRC)) {
        return ECAM_E_PAYLOAD_CRC;
    }
    ecam_prepare(blob, &candidate);
    *t = candidate;
    return ECAM_OK;
}

/* Stable identifiers for logs and test drivers; unknown codes get a generic name. */
const char *ecam_status_name(int status)
{
    switch (status) {
    case ECAM_OK:
        return "ECAM_OK";
    case ECAM_E_SHORT:
        return "ECAM_E_SHORT";
    case ECAM_E_MAGIC:
        return "ECAM_E_MAGIC";
    case ECAM_E_VERSION:
        return "ECAM_E_VERSION";
    case ECAM_E_HEADER_SIZE:
        return "ECAM_E_HEADER_SIZE";
    case ECAM_E_HEADER_CRC:
        return "ECAM_E_HEADER_CRC";
    case ECAM_E_FIELD:
        return "ECAM_E_FIELD";
    case ECAM_E_LENGTH:
        return "ECAM_E_LENGTH";
    case ECAM_E_PAYLOAD_CRC:
        return "ECAM_E_PAYLOAD_CRC";
    case ECAM_E_NULL:
        return "ECAM_E_NULL";
    default:
        return "ECAM_E_UNKNOWN";
    }
}
