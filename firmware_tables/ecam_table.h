/*
 * ecam_table.h - C99 reference runtime for ecam cam tables, format version 1.
 *
 * The blob layout and the integer lookup arithmetic are specified in FORMAT.md; this runtime
 * follows it bit for bit, so it agrees exactly with the Python CamTable.lookup.
 *
 * No allocation, no mutable globals, no floating point, no divide instruction in the lookup path.
 * The table refers to the caller's blob (flash or RAM) and never copies it: the blob must outlive
 * the table and must not change after ecam_table_init.
 */
#ifndef ECAM_TABLE_H
#define ECAM_TABLE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define ECAM_FORMAT_VERSION 1
#define ECAM_HEADER_BYTES 64

/* Result of ecam_table_init; every rejection reason of FORMAT.md has its own code. */
typedef enum ecam_status {
    ECAM_OK = 0,
    ECAM_E_SHORT = -1,       /* length shorter than the 64-byte header */
    ECAM_E_MAGIC = -2,       /* bytes 0..3 are not "ECAM" */
    ECAM_E_VERSION = -3,     /* format_version is not 1 */
    ECAM_E_HEADER_SIZE = -4, /* header_bytes is not 64 */
    ECAM_E_HEADER_CRC = -5,  /* header_crc32 does not match bytes 0..59 */
    ECAM_E_FIELD = -6,       /* a header field breaks its rule (incl. reserved, tau_recip) */
    ECAM_E_LENGTH = -7,      /* total length is not 64 + payload_bytes */
    ECAM_E_PAYLOAD_CRC = -8, /* payload_crc32 does not match the payload */
    ECAM_E_NULL = -9         /* a NULL table or blob pointer */
} ecam_status;

/*
 * A validated view of one blob. Treat the members as private: they are filled by
 * ecam_table_init and only read by the lookup functions.
 */
typedef struct ecam_table {
    const uint8_t *position;  /* payload array 1 (points little-endian int32, Q(Qy)) */
    const uint8_t *slope;     /* payload array 2, NULL for degree 1 */
    const uint8_t *curvature; /* payload array 3, NULL unless degree 5 */
    uint64_t tau_recip;       /* R = ceil(2^(32+F) / h), from the header */
    uint64_t mod_recip;       /* floor((2^64 - 1) / M), Barrett reciprocal for the period */
    uint32_t master_counts;   /* M */
    uint32_t step_counts;     /* h */
    uint32_t step_recip;      /* floor(2^32 / h) when h is not a power of two, else 0 */
    uint32_t mod_offset;      /* 2^63 mod M, undoes the int64 -> uint64 bias of the period wrap */
    uint32_t intervals;       /* N = points - 1 */
    int8_t step_shift;        /* k when h = 2^k, else -1 */
    uint8_t degree;           /* 1, 3 or 5 */
    uint8_t periodic;         /* 1 when the master axis wraps every M counts */
    uint8_t tau_bits;         /* F */
    uint8_t work_bits;        /* W */
    uint8_t slope_bits;       /* Qa */
    uint8_t curvature_bits;   /* Qb */
    uint8_t slope_preshift;   /* P */
    uint8_t position_bits;    /* Qy */
} ecam_table;

/* Validate blob[0..len) against FORMAT.md and bind t to it; on failure t is cleared and the
 * status (negative) is returned, so a failed table looks up as position 0, slope 0. */
int ecam_table_init(ecam_table *t, const uint8_t *blob, size_t len);

/* Readable name of a status code ("ECAM_E_HEADER_CRC", ...), for logs and the CLI. */
const char *ecam_status_name(int status);

/* Slave position (counts) at any master position (counts); periodic tables wrap. */
int32_t ecam_table_position(const ecam_table *t, int64_t master_counts);

/* Slave velocity ratio at any master position: Q16 slave counts per master count. */
int32_t ecam_table_slope(const ecam_table *t, int64_t master_counts);

/* Position and slope in one pass; either output pointer may be NULL to skip that output. */
void ecam_table_lookup(const ecam_table *t, int64_t master_counts, int32_t *position,
                       int32_t *slope);

/* IEEE 802.3 CRC-32, the same value as zlib.crc32(data); data may be NULL only when len is 0. */
uint32_t ecam_crc32(const uint8_t *data, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* ECAM_TABLE_H */
