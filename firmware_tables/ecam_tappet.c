/* ecam_tappet.c - a digital cam switch (tappet) for firmware; see ecam_tappet.h. */
#include "ecam_tappet.h"

#define ECAM_TAPPET_MICROSECONDS 1000000
#define ECAM_TAPPET_MAX_COMPENSATION_US 100000000

/* a mod b into 0 .. b-1 for b > 0 (C's % truncates towards zero). */
static int64_t ecam_tappet_mod(int64_t a, int64_t b)
{
    int64_t r = a % b;
    return r < 0 ? r + b : r;
}

/* a / b rounded half away from zero, b > 0, |a| < 2^62. */
static int64_t ecam_tappet_div_round(int64_t a, int64_t b)
{
    int64_t half = b / 2;
    return a >= 0 ? (a + half) / b : -((-a + half) / b);
}

/* Distance of two positions on the circle of period counts. */
static int64_t ecam_tappet_distance(int64_t a, int64_t b, int64_t period)
{
    int64_t d = ecam_tappet_mod(a - b, period);
    return d < period - d ? d : period - d;
}

/* 1 when every field of the track is within its range. */
static int ecam_tappet_valid(const ecam_tappet_track *t)
{
    int32_t limit = ECAM_TAPPET_MAX_COMPENSATION_US;
    if (t->period_counts < 2u || t->period_counts > 0x80000000u) {
        return 0;
    }
    if (t->on_counts >= t->period_counts || t->off_counts >= t->period_counts) {
        return 0;
    }
    if (t->hysteresis_counts > t->period_counts / 2u || t->direction > ECAM_TAPPET_NEGATIVE) {
        return 0;
    }
    return t->on_compensation_us >= -limit && t->on_compensation_us <= limit &&
           t->off_compensation_us >= -limit && t->off_compensation_us <= limit;
}

void ecam_tappet_init(ecam_tappet_state *state)
{
    if (state != 0) {
        state->output = 0u;
        state->direction = 0;
        state->armed = 1u;
        state->last_switch_counts = 0u;
    }
}

int ecam_tappet_step(const ecam_tappet_track *track, ecam_tappet_state *state, int64_t master_counts,
                     int32_t speed_counts_per_s)
{
    int64_t period, position, shift_on, shift_off, length, on;
    int8_t direction;
    int inside, allowed, wanted;
    uint8_t armed;
    int64_t last;
    if (track == 0 || state == 0) {
        return ECAM_TAPPET_ERR_ARG;
    }
    if (!ecam_tappet_valid(track)) {
        return ECAM_TAPPET_ERR_TRACK;
    }
    period = (int64_t)track->period_counts;
    position = ecam_tappet_mod(master_counts, period);
    direction = speed_counts_per_s > 0 ? 1 : (speed_counts_per_s < 0 ? -1 : state->direction);
    /* the compensated window: an edge at p happens at p + speed x compensation */
    shift_on = ecam_tappet_div_round((int64_t)speed_counts_per_s * track->on_compensation_us,
                                     ECAM_TAPPET_MICROSECONDS);
    shift_off = ecam_tappet_div_round((int64_t)speed_counts_per_s * track->off_compensation_us,
                                      ECAM_TAPPET_MICROSECONDS);
    length = ecam_tappet_mod((int64_t)track->off_counts - (int64_t)track->on_counts, period) + shift_off -
             shift_on;
    on = ecam_tappet_mod((int64_t)track->on_counts + shift_on, period);
    if (length < 0) {
        inside = 0;
    } else if (length >= period) {
        inside = 1;
    } else {
        inside = ecam_tappet_mod(position - on, period) <= length;
    }
    allowed = track->direction == ECAM_TAPPET_BOTH || (track->direction == ECAM_TAPPET_POSITIVE && direction == 1) ||
              (track->direction == ECAM_TAPPET_NEGATIVE && direction == -1);
    wanted = inside && allowed;
    armed = state->armed;
    last = (int64_t)state->last_switch_counts;
    if (!armed && ecam_tappet_distance(position, last, period) >= (int64_t)track->hysteresis_counts) {
        armed = 1u;
    }
    if ((uint8_t)wanted != state->output && armed) {
        state->output = (uint8_t)wanted;
        last = position;
        armed = track->hysteresis_counts == 0u ? 1u : 0u;
    }
    state->direction = direction;
    state->armed = armed;
    state->last_switch_counts = (uint32_t)last;
    return (int)state->output;
}
