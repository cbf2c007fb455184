/*
 * ecam_minimal.h - minimal fixed-point lookups of one known table, for measurement only
 * (see ecam_minimal.c). Arrays are aligned native int32; master is inside [0, M).
 */
#ifndef ECAM_MINIMAL_H
#define ECAM_MINIMAL_H

#include <stdint.h>

int32_t ecam_minimal_linear(const int32_t *position, uint32_t master);
int32_t ecam_minimal_cubic(const int32_t *position, const int32_t *slope, uint32_t master);
int32_t ecam_minimal_quintic(const int32_t *position, const int32_t *slope,
                             const int32_t *curvature, uint32_t master);

/* Precomputed coefficients per interval: the expanded form's int64 words (ecam_poly_init), and
 * int32 words in whole counts with the fraction in Q16 (see ecam_minimal.c). */
int32_t ecam_minimal_expanded_linear(const int64_t *c, uint32_t master);
int32_t ecam_minimal_expanded_cubic(const int64_t *c, uint32_t master);
int32_t ecam_minimal_expanded_quintic(const int64_t *c, uint32_t master);
int32_t ecam_minimal_q16_linear(const int32_t *c, uint32_t master);
int32_t ecam_minimal_q16_cubic(const int32_t *c, uint32_t master);
int32_t ecam_minimal_q16_quintic(const int32_t *c, uint32_t master);

#endif /* ECAM_MINIMAL_H */
