/*
 * ecam_table.h - C99 reference runtime for ecam cam tables, format versions 1, 2 and 3.
 *
 * The blob layout, the loader's rules and the integer lookup arithmetic are specified in
 * FORMAT.md; this runtime follows it bit for bit, so it agrees exactly with the Python
 * CamTable.lookup, and its loader accepts exactly the blobs CamTable.from_bytes accepts.
 *
 * No allocation, no mutable globals, no floating point, no divide instruction in the lookup path
 * (but one: on a core that divides in one instruction, ECAM_HW_DIVIDE, e.g. the Cortex-M3/M4/M7,
 * ecam_poly_position wraps a table with h = 2^k by two 32-bit remainders; -DECAM_HW_DIVIDE=0
 * keeps it divide-free).
 * The table refers to the caller's blob (flash or RAM) and never copies it: the blob must outlive
 * the table and must not change after ecam_table_init.
 *
 * Net stroke (format version 2): a periodic table may advance its slave by N/D counts per period;
 * the position then adds floor((k N + floor(D/2)) / D) for the k whole periods passed
 * (FORMAT.md step 7) and is returned as the int32 two's-complement wrap of that exact value, as
 * a CiA 402 position rolls over. The slope has no net term.
 *
 * Ramp (format version 3): a large net stroke stores its data relative to its ramp, S = floor(N /
 * (D M)) whole counts per master count, so that the stored positions keep their fraction bits in
 * int32; the position adds S * (m mod M), the slope S * 2^16 (FORMAT.md step 8).
 *
 * Failed and uninitialised tables: a table whose ecam_table_init failed, and a zero-filled table
 * that was never initialised (static storage), are "not ready". Every lookup on them returns
 * ECAM_INVALID (INT32_MIN) for the position and for the slope, a value no accepted table without
 * a net stroke ever returns (FORMAT.md, "Overflow proof"), so it is never mistaken for a servo
 * command. (A net stroke's position wraps through all of int32, INT32_MIN included.)
 * ecam_table_ready() says whether a table is usable; ecam_table_status() says why not: check it
 * once before enabling the axis rather than testing each value.
 *
 * Switching tables while an interrupt reads: never call ecam_table_init on a table an interrupt
 * may be reading. Use an ecam_table_pair (double buffer, one pointer store publishes the new
 * table): the main loop calls ecam_pair_load, the interrupt calls ecam_pair_acquire once per
 * invocation and looks up in the table it returns. See the pair functions below.
 */
#ifndef ECAM_TABLE_H
#define ECAM_TABLE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define ECAM_FORMAT_VERSION 3 /* the newest blob format read; versions 1, 2 and 3 load */
#define ECAM_HEADER_BYTES 64

/* Position and slope that every lookup on a table that is not ready returns (no accepted table
 * returns it, except as the int32 wrap of a net stroke's position: see above). */
#define ECAM_INVALID INT32_MIN

/*
 * Result of ecam_table_init: 0, or the negative code of the first rule of FORMAT.md the blob
 * breaks. Every rejection rule has its own code; the loader checks them in FORMAT.md's order:
 * the envelope (-1..-5), the field rules (-10..-24, then -34, -36), the length (-7), the payload CRC
 * (-8), then the overflow proof (-25..-31).
 */
typedef enum ecam_status {
    ECAM_OK = 0,
    /* envelope */
    ECAM_E_SHORT = -1,       /* length shorter than the 64-byte header */
    ECAM_E_MAGIC = -2,       /* bytes 0..3 are not "ECAM" */
    ECAM_E_VERSION = -3,     /* format_version is not 1, 2 or 3 */
    ECAM_E_HEADER_SIZE = -4, /* header_bytes is not 64 */
    ECAM_E_HEADER_CRC = -5,  /* header_crc32 does not match bytes 0..59 */
    ECAM_E_FIELD = -6,       /* no longer returned: each field rule has its own code below */
    ECAM_E_LENGTH = -7,      /* total length is not 64 + payload_bytes */
    ECAM_E_PAYLOAD_CRC = -8, /* payload_crc32 does not match the payload */
    ECAM_E_NULL = -9,        /* a NULL table or blob pointer */
    /* field rules (checked after the header CRC, before the length, in this order) */
    ECAM_E_DEGREE = -10,         /* degree is not 1, 3 or 5 */
    ECAM_E_FLAGS = -11,          /* a flag bit other than bit 0 (periodic) is set */
    ECAM_E_RESERVED = -12,       /* a reserved byte (29..31; 48..59 in version 1) is not 0 */
    ECAM_E_POINTS = -13,         /* points < 2 */
    ECAM_E_MASTER_COUNTS = -14,  /* master_counts outside 2..2^31 */
    ECAM_E_STEP_COUNTS = -15,    /* step_counts outside 1..2^30, or (points - 1) * h != M */
    ECAM_E_STEP_SHIFT = -16,     /* step_shift is not k for h = 2^k, or not -1 otherwise */
    ECAM_E_TAU_BITS = -17,       /* tau_bits outside ceil(log2 h)..30, or not k for h = 2^k */
    ECAM_E_TAU_RECIP = -18,      /* tau_recip is not ceil(2^(32+F) / h) */
    ECAM_E_POSITION_BITS = -19,  /* position_bits above 30 */
    ECAM_E_WORK_BITS = -20,      /* work_bits outside Qy..40, or not Qy for linear */
    ECAM_E_SLOPE_BITS = -21,     /* slope_bits above W, or not 0 for linear */
    ECAM_E_CURVATURE_BITS = -22, /* curvature_bits above W, or not 0 unless quintic */
    ECAM_E_SLOPE_PRESHIFT = -23, /* 16 + F + W - P outside 0..63 */
    ECAM_E_PAYLOAD_BYTES = -24,  /* payload_bytes is not points * 4 * V */
    /* overflow proof (after the payload CRC), interval by interval, in this order */
    ECAM_E_POINT_RANGE = -25,         /* |position * 2^(W-Qy)| >= 2^62 */
    ECAM_E_HORNER_RANGE = -26,        /* a position Horner product may leave int64 */
    ECAM_E_SUM_RANGE = -27,           /* the final position sum may leave int64 */
    ECAM_E_POSITION_RANGE = -28,      /* the position may leave -(2^31 - 1)..2^31 - 1 */
    ECAM_E_SLOPE_HORNER_RANGE = -29,  /* a slope Horner product or sum may leave int64 */
    ECAM_E_SLOPE_PRODUCT = -30,       /* asr(q, P) * tau_recip may leave int64 */
    ECAM_E_SLOPE_RANGE = -31,         /* the slope may leave -(2^31 - 1)..2^31 - 1 */
    /* not loader rules */
    ECAM_E_UNINITIALISED = -32, /* ecam_table_status of a zero-filled, never initialised table */
    ECAM_E_BUSY = -33,          /* ecam_pair_load: the interrupt still reads the spare table */
    /* version 2 (checked after the field rules, before the length) */
    ECAM_E_NET_STROKE = -34, /* net stroke N/D not reduced, D = 0, |N/D| >= 2^31, or not periodic */
    /* the expanded form (ecam_poly_init; not a loader rule) */
    ECAM_E_BUFFER = -35, /* the caller's buffer is smaller than ecam_poly_bytes(table) */
    /* version 3 (checked after ECAM_E_NET_STROKE, before the length) */
    ECAM_E_RAMP = -36 /* version 3 without a net stroke, or its ramp S beyond +-(2^15 - 1) */
} ecam_status;

typedef struct ecam_table ecam_table;

/* The kernels of one degree and step kind, chosen by ecam_table_init (any master). */
typedef int32_t (*ecam_position_kernel)(const ecam_table *table, int64_t master_counts);
typedef int32_t (*ecam_slope_kernel)(const ecam_table *table, int64_t master_counts);
/* The continuations of one degree for a master already inside [0, M) (a net stroke's wrap and
 * ecam_table_lookup reach them by a tail call, so their frames never stack on another): the
 * position plus a term modulo 2^32, and both outputs in one pass. */
typedef int32_t (*ecam_position_at_kernel)(const ecam_table *table, uint32_t local, uint32_t term);
typedef void (*ecam_lookup_at_kernel)(const ecam_table *table, int32_t *position, uint32_t local,
                                      uint32_t term, int32_t *slope);

/*
 * A validated view of one blob, with its format precomputed. Treat the members as private: they
 * are filled by ecam_table_init and only read by the lookup functions. All zero means "never
 * initialised" (not ready).
 */
struct ecam_table {
    ecam_position_kernel position_kernel; /* NULL unless ready */
    ecam_slope_kernel slope_kernel;       /* NULL unless ready */
    ecam_position_kernel position_outside; /* the position kernels' path past [0, M) */
    ecam_position_at_kernel position_at;  /* the position inside [0, M) plus a net term */
    ecam_lookup_at_kernel lookup_at;      /* both outputs inside [0, M), plus a net term */
    const uint8_t *position;              /* payload array 1 (little-endian int32, Q(Qy)) */
    const uint8_t *slope;                 /* payload array 2, NULL for degree 1 */
    const uint8_t *curvature;             /* payload array 3, NULL unless degree 5 */
    uint64_t master_limit;                /* M, as a 64-bit word: the one-compare range test */
    uint64_t tau_recip;                   /* R = ceil(2^(32+F) / h), from the header */
    uint64_t mod_recip;                   /* floor((2^64 - 1) / M), Barrett reciprocal */
    uint64_t half;                        /* 2^(W-1), or 0 when W = 0 */
    uint64_t out_mul;                     /* 32-bit cores' final shift: 2^(32-S) if S <= 32, else 1 */
    uint64_t period_bias;                 /* floor(2^63 / M): whole periods of the wrap's bias */
    uint64_t net_recip;                   /* floor((2^64 - 1) / D) (net stroke N/D per period) */
    uint64_t net_bias;                    /* floor(2^63 / D) */
    uint64_t round;                       /* the position kernels' rounding term: half, or
                                             half * 2^F for linear */
    uint64_t position_scale;              /* 2^(W-Qy) */
    uint64_t slope_scale;                 /* 2^(W-Qa) */
    uint64_t curvature_scale;             /* 2^(W-Qb) */
    uint32_t master_counts;               /* M */
    uint32_t step_counts;                 /* h */
    uint32_t step_recip;                  /* floor(2^32 / h) when h is not a power of two */
    uint32_t step_mask;                   /* h - 1 when h is a power of two */
    uint32_t mod_offset;                  /* 2^63 mod M (32-bit cores' wrap) */
    uint32_t mod_complement;              /* M - mod_offset */
    uint32_t tau_one;                     /* 2^F (linear kernel) */
    uint32_t intervals;                   /* N = points - 1 */
    int32_t end_position[2];              /* not periodic: the position below 0, at or past M */
    int32_t multiplier[14];               /* w * 2^(W-Qa), w * 2^(W-Qb): 32-bit quintic kernel */
    int32_t status;                       /* ECAM_OK when ready, else why init failed */
    uint32_t net_whole;                   /* A = floor(N / D), as int32 bits */
    uint32_t net_rest;                    /* B = N mod D */
    uint32_t net_den;                     /* D (1 when there is no net stroke) */
    uint32_t net_half;                    /* floor(D / 2) */
    uint32_t net_bias_rest;               /* 2^63 mod D */
    uint8_t degree;                       /* 1, 3 or 5 */
    uint8_t periodic;                     /* outside [0, M): 0 clamp, 1 wrap, 2 wrap + net stroke */
    uint8_t position_wide;                /* 1 when 2^(W-Qy) > 2^30 (32-bit cores' kernels) */
    uint8_t step_shift;                   /* k when h = 2^k */
    uint8_t tau_bits;                     /* F */
    uint8_t tau_lshift;                   /* (32 - F) mod 32: tau * 2^(32-F) on 32-bit cores */
    uint8_t work_bits;                    /* W */
    uint8_t out_shift;                    /* S, the kernels' final shift: W, or F + W (linear) */
    uint8_t out_rshift;                   /* 32-bit cores' final shift: S - 32 if S > 32, else 0 */
    uint8_t slope_preshift;               /* P */
    uint8_t slope_out_shift;              /* 16 + F + W - P */
    /* version 3 (zero otherwise): the ramp S of step 8 and the degree's own continuations, which
     * the ramp's kernels call with its term added */
    ecam_position_at_kernel ramp_at;      /* the degree's position_at */
    ecam_slope_kernel ramp_slope_kernel;  /* the degree's slope kernel */
    uint32_t ramp;                        /* S, as int32 bits */
    uint32_t ramp_slope;                  /* S * 2^16, as int32 bits */
};

/*
 * Validate blob[0..len) against FORMAT.md (every field rule and the overflow proof) and bind t to
 * it. Returns ECAM_OK, or the negative ecam_status of the first rule that fails; t is then not
 * ready: its lookups return ECAM_INVALID and ecam_table_status(t) returns the same code.
 * Not safe while an interrupt reads t: use ecam_pair_load for that.
 */
int ecam_table_init(ecam_table *t, const uint8_t *blob, size_t len);

/* 1 when t is an initialised table that looks up, 0 otherwise (NULL, failed, never initialised). */
int ecam_table_ready(const ecam_table *t);

/* ECAM_OK when ready; else the code init failed with, ECAM_E_UNINITIALISED or ECAM_E_NULL. */
int ecam_table_status(const ecam_table *t);

/* Readable name of a status code ("ECAM_E_HEADER_CRC", ...), for logs and the CLI. */
const char *ecam_status_name(int status);

/* Slave position (counts) at any master position (counts); periodic tables wrap.
 * ECAM_INVALID when t is NULL or not ready. */
int32_t ecam_table_position(const ecam_table *t, int64_t master_counts);

/* Slave velocity ratio at any master position: Q16 slave counts per master count.
 * ECAM_INVALID when t is NULL or not ready. */
int32_t ecam_table_slope(const ecam_table *t, int64_t master_counts);

/* Position and slope in one pass; either output pointer may be NULL to skip that output.
 * Both outputs are ECAM_INVALID when t is NULL or not ready. */
void ecam_table_lookup(const ecam_table *t, int64_t master_counts, int32_t *position,
                       int32_t *slope);

/* IEEE 802.3 CRC-32, the same value as zlib.crc32(data); data may be NULL only when len is 0. */
uint32_t ecam_crc32(const uint8_t *data, size_t len);

/*
 * Double buffer for switching tables while an interrupt looks up (single core; the loader runs
 * at a lower priority than every reader, e.g. the main loop against a control interrupt).
 *
 *   main loop:  ecam_pair_init(&pair) once; then rc = ecam_pair_load(&pair, blob, len)
 *   interrupt:  const ecam_table *t = ecam_pair_acquire(&pair);
 *               position = ecam_table_position(t, master);   (t is used only in this invocation)
 *
 * ecam_pair_load validates the blob into the spare table while the interrupt keeps reading the
 * active one, then publishes it with one pointer store: each interrupt sees the old table or the
 * new one, never a mix and never a table being written. A rejected blob leaves the active table
 * as it was. The spare table is reused only after the interrupt has acquired the new one
 * (ecam_pair_idle); until then ecam_pair_load returns ECAM_E_BUSY. The blob of a replaced table
 * may be overwritten once ecam_pair_idle returns 1 after the load that replaced it.
 * Set ECAM_MEMORY_BARRIER() to a hardware barrier (e.g. __DMB()) if the reader runs on another
 * core; the default is volatile ordering, which suffices on a single core.
 */
typedef struct ecam_table_pair {
    ecam_table table[2];
    const ecam_table *volatile active; /* what ecam_pair_acquire returns */
    volatile uint32_t published;       /* tables published so far */
    volatile uint32_t seen;            /* `published` as the interrupt last saw it */
} ecam_table_pair;

/* Both tables not ready; acquire returns a table whose lookups give ECAM_INVALID until a load. */
void ecam_pair_init(ecam_table_pair *pair);

/* Validate blob into the spare table and publish it; ECAM_OK, a loader code or ECAM_E_BUSY. */
int ecam_pair_load(ecam_table_pair *pair, const uint8_t *blob, size_t len);

/* The table to use for this interrupt invocation (never NULL after ecam_pair_init). */
const ecam_table *ecam_pair_acquire(ecam_table_pair *pair);

/* 1 when the interrupt has acquired the latest table, so the spare one is no longer read. */
int ecam_pair_idle(const ecam_table_pair *pair);

/*
 * The expanded form (FORMAT.md "Expanded form"): the same table with its per-interval polynomial
 * precomputed into a buffer the caller provides, for a lookup that is one Horner chain (no
 * Hermite coefficients per call). Same results as ecam_table_position, bit for bit, for every
 * int64 master; the trade is RAM for instructions:
 *
 *   RAM  ecam_poly_bytes(t) = (points - 1) * (degree + 1) * 8 bytes (quintic: 48 B per interval,
 *        4 times the 12 B per point of the blob; cubic 32 B, 2.7 times; linear 16 B, 4 times),
 *        plus sizeof(ecam_poly).
 *
 *   static int64_t coefficients[ECAM_POLY_WORDS(64, 5)];   (64 intervals, quintic: 3 KB)
 *   rc = ecam_poly_init(&poly, &table, coefficients, sizeof coefficients);
 *   position = ecam_poly_position(&poly, master);
 *
 * The expansion reads the table's blob once (init); the lookup reads only the buffer inside the
 * period, and the table (which must stay initialised and unchanged) for a master outside it: the
 * wrap, the clamp and a net stroke's step 7 are the table's. Not safe while an interrupt reads p:
 * expand into a second ecam_poly and publish a pointer to it.
 */
#define ECAM_POLY_WORDS(intervals, degree) ((size_t)(intervals) * ((size_t)(degree) + 1u))

typedef struct ecam_poly ecam_poly;
typedef int32_t (*ecam_poly_kernel)(const ecam_poly *poly, int64_t master_counts);

struct ecam_poly {
    ecam_poly_kernel kernel;   /* NULL unless ready */
    const int64_t *coefficient; /* per interval: Y0 2^(W-Qy) + half, c1 .. cn (FORMAT.md step 4) */
    const ecam_table *table;   /* step 1 (wrap, clamp) and step 7 past [0, M) */
    uint64_t master_limit;     /* M */
    uint64_t tau_recip;        /* R */
    uint64_t out_mul;          /* 32-bit cores' final shift W: 2^(32-W) if W <= 32, else 1 */
    uint32_t step_counts;      /* h */
    uint32_t step_recip;       /* floor(2^32 / h) when h is not a power of two */
    uint32_t step_mask;        /* h - 1 when h is a power of two */
    int32_t status;            /* ECAM_OK when ready, else why init failed */
    uint8_t degree;            /* n */
    uint8_t step_shift;        /* k when h = 2^k */
    uint8_t tau_bits;          /* F */
    uint8_t tau_lshift;        /* (32 - F) mod 32 */
    uint8_t work_bits;         /* W */
    uint8_t out_rshift;        /* 32-bit cores' final shift: W - 32 if W > 32, else 0 */
    uint8_t narrow_lshift;     /* 31 - F: the narrow kernels' fraction tau 2^(31-F) */
    uint8_t outside;           /* past [0, M): 0 the wrap, 1 the wrap and a whole net stroke
                                  (both inline), 2 the clamp or a fractional net stroke */
    ecam_poly_kernel ramp_kernel; /* version 3: the kernel the ramp's kernel calls (else NULL) */
    uint32_t master_mask;      /* M - 1 (a period of M = 2^j: the wrap is m & (M - 1)) */
    uint8_t master_shift;      /* j when M = 2^j and the mask kernels run, else 0 */
    uint16_t fold_count;       /* N, when h = 2^k and a divide instruction wraps (else 0) */
    uint16_t fold_factor;      /* 2^(32-k) mod N (the same wrap) */
    uint32_t ramp;             /* version 3: S of step 8, as int32 bits (else 0) */
    uint32_t fold_bias;        /* N (N - 1) (the same wrap) */
};

/* Bytes of int64 buffer the expansion of t needs; 0 when t is NULL or not ready. */
size_t ecam_poly_bytes(const ecam_table *t);

/* Expand t into buffer[0 .. ecam_poly_bytes(t)); ECAM_OK, or ECAM_E_NULL, the table's own status
 * when it is not ready, or ECAM_E_BUFFER; on failure p is not ready (its lookups return
 * ECAM_INVALID). */
int ecam_poly_init(ecam_poly *p, const ecam_table *t, int64_t *buffer, size_t buffer_bytes);

/* The slave position at any master: ecam_table_position(t, m) bit for bit, through the buffer.
 * ECAM_INVALID when p is NULL or not ready. */
int32_t ecam_poly_position(const ecam_poly *p, int64_t master_counts);

#ifdef __cplusplus
}
#endif

#endif /* ECAM_TABLE_H */
