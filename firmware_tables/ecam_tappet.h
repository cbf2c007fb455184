/* ecam_tappet.h - a digital cam switch (tappet) evaluated for firmware, bit-exact with
 * ecam.tappet.TappetCounts.step (Python). C99, integer only, no allocation, no globals.
 *
 * PLCopen's digital cam switch (MC_DigitalCamSwitch): the output is on from FirstOnPosition to
 * LastOnPosition (a last position below the first wraps through the period end), only in the
 * master direction AxisDirection allows (0 both, 1 positive, 2 negative), with the track's
 * OnCompensation / OffCompensation (negative: the edge is brought forward, as an actuator's dead
 * time needs) and Hysteresis (move this far from the last switching point before switching
 * again). See ecam/tappet.py for the documents these follow.
 */
#ifndef ECAM_TAPPET_H
#define ECAM_TAPPET_H

#include <stdint.h>

#define ECAM_TAPPET_BOTH 0u     /* PLCopen AxisDirection 0 */
#define ECAM_TAPPET_POSITIVE 1u /* AxisDirection 1 */
#define ECAM_TAPPET_NEGATIVE 2u /* AxisDirection 2 */

#define ECAM_TAPPET_ERR_ARG (-1)   /* a NULL pointer */
#define ECAM_TAPPET_ERR_TRACK (-2) /* a field of the track out of its range */

/* One track. Range / unit of each field: */
typedef struct {
    uint32_t period_counts;      /* master counts per period, 2 .. 2^31 */
    uint32_t on_counts;          /* first on position, 0 .. period-1 [counts] */
    uint32_t off_counts;         /* last on position, 0 .. period-1 [counts] */
    uint32_t hysteresis_counts;  /* 0 .. period/2 [counts] */
    int32_t on_compensation_us;  /* -1e8 .. 1e8 [us]; < 0 leads, > 0 delays */
    int32_t off_compensation_us; /* -1e8 .. 1e8 [us] */
    uint8_t direction;           /* ECAM_TAPPET_BOTH / _POSITIVE / _NEGATIVE */
} ecam_tappet_track;

/* What a track remembers between samples. */
typedef struct {
    uint8_t output;              /* 0 off, 1 on */
    int8_t direction;            /* last direction of motion: +1, -1; 0 before the first move */
    uint8_t armed;               /* 1: a switch may happen (hysteresis left behind) */
    uint32_t last_switch_counts; /* master position of the last switch, 0 .. period-1 */
} ecam_tappet_state;

/* The state of a track that has not run yet: output off, no direction, armed. */
void ecam_tappet_init(ecam_tappet_state *state);

/* One sample: master position [counts, any int64] and speed [counts/s]; updates the state and
 * returns the output (0 or 1), or a negative ECAM_TAPPET_ERR_* code (the state untouched). */
int ecam_tappet_step(const ecam_tappet_track *track, ecam_tappet_state *state, int64_t master_counts,
                     int32_t speed_counts_per_s);

#endif /* ECAM_TAPPET_H */
