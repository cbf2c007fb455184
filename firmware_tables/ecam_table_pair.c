/* ecam_table_pair.c - a running and a pending cam table switched at a period boundary; see
 * ecam_table_pair.h for the rules (PLCopen coordinates, the boundary, concurrency). */
#include "ecam_table_pair.h"

#include <stddef.h>

#ifndef ECAM_MEMORY_BARRIER
#define ECAM_MEMORY_BARRIER() ((void)0)
#endif

/* ecam_switch_pair.state: one byte tested on the hot path, 0 while the window is valid. */
#define ECAM_SWITCH_TRACKING 0u
#define ECAM_SWITCH_FIRST 1u
#define ECAM_SWITCH_ENDED 2u

/* Two's-complement reinterpretations written out, because C99 leaves the conversion of an
 * out-of-range unsigned value to a signed type implementation-defined; compilers reduce each to
 * nothing. */
static int64_t ecam_switch_s64(uint64_t u)
{
    return u <= (uint64_t)INT64_MAX ? (int64_t)u : -(int64_t)(~u) - 1;
}

static int32_t ecam_switch_s32(uint32_t u)
{
    return u <= (uint32_t)INT32_MAX ? (int32_t)u : -(int32_t)(~u) - 1;
}

/* The start of the period holding `local` (floor(local / M) M, as local - (local mod M), so
 * nothing overflows): the only division, taken once per period, not per sample. A table that
 * does not repeat has one period, its range, starting at 0. */
static uint64_t ecam_switch_window(const ecam_table *t, uint64_t local)
{
    int64_t m, r;
    if (t->periodic == 0u) {
        return 0u;
    }
    m = (int64_t)t->master_counts;
    r = ecam_switch_s64(local) % m;
    if (r < 0) {
        r += m; /* C99 % truncates toward 0; the period is the floor's */
    }
    return local - (uint64_t)r;
}

/* ECAM_SWITCH_ENDED when `local` lies outside the master range of a table that does not
 * repeat, else ECAM_SWITCH_TRACKING. */
static uint8_t ecam_switch_state(const ecam_table *t, uint64_t local, uint64_t window)
{
    return (t->periodic == 0u && (local - window) >= (uint64_t)t->master_counts) ? ECAM_SWITCH_ENDED
                                                                                : ECAM_SWITCH_TRACKING;
}

/* Make `t` the running table: what the hot path reads of it, cached in the pair. */
static void ecam_switch_run(ecam_switch_pair *pair, const ecam_table *t)
{
    pair->running = t;
    pair->span = (uint64_t)t->master_counts;
    pair->repeat = t->periodic == 1u ? 1u : 0u;
}

void ecam_switch_init(ecam_switch_pair *pair)
{
    if (pair != NULL) {
        pair->running = NULL;
        pair->pending = NULL;
        pair->armed = 0u;
        pair->mode = 0u;
        pair->switches = 0u;
        pair->pending_master = 0u;
        pair->origin = 0u;
        pair->window = 0u;
        pair->boundary = 0u;
        pair->pending_slave = 0u;
        pair->offset = 0u;
        pair->span = 0u;
        pair->state = ECAM_SWITCH_FIRST;
        pair->repeat = 0u;
    }
}

int ecam_switch_engage(ecam_switch_pair *pair, const ecam_table *table, int64_t master_offset,
                       int32_t slave_offset)
{
    if (pair == NULL || table == NULL) {
        return ECAM_SWITCH_E_NULL;
    }
    if (!ecam_table_ready(table)) {
        return ECAM_SWITCH_E_TABLE;
    }
    ecam_switch_init(pair);
    /* CODESYS: X = MasterPosition + MasterOffset, so the table's 0 sits at -MasterOffset */
    pair->origin = 0u - (uint64_t)master_offset;
    pair->offset = (uint32_t)slave_offset;
    ecam_switch_run(pair, table);
    return ECAM_SWITCH_OK;
}

int ecam_switch_arm(ecam_switch_pair *pair, const ecam_table *table, unsigned mode,
                    int64_t master_offset, int32_t slave_offset)
{
    if (pair == NULL || table == NULL) {
        return ECAM_SWITCH_E_NULL;
    }
    if (pair->running == NULL) {
        return ECAM_SWITCH_E_NOT_ENGAGED;
    }
    if (pair->armed != 0u) {
        return ECAM_SWITCH_E_ARMED;
    }
    if (!ecam_table_ready(table)) {
        return ECAM_SWITCH_E_TABLE;
    }
    if ((mode & ~(ECAM_SWITCH_MASTER_RELATIVE | ECAM_SWITCH_SLAVE_RELATIVE)) != 0u) {
        return ECAM_SWITCH_E_MODE;
    }
    /* A table that does not repeat must be entered inside its range (CODESYS reports
     * SMC_CI_MASTER_OUT_OF_SCALE mid-motion; firmware refuses it here). Master absolute enters it
     * wherever the boundary falls, and a running periodic table has a boundary at every multiple
     * of its period: refused. Master relative enters it at MasterOffset: that must lie in
     * 0..M. */
    if (table->periodic == 0u &&
        ((mode & ECAM_SWITCH_MASTER_RELATIVE) == 0u || master_offset < 0 ||
         master_offset > (int64_t)table->master_counts)) {
        return ECAM_SWITCH_E_MASTER_RANGE;
    }
    /* Not armed, so the interrupt reads none of these now; the flag is stored last. */
    pair->pending = table;
    pair->mode = (uint32_t)mode;
    pair->pending_master = (uint64_t)master_offset;
    pair->pending_slave = (uint32_t)slave_offset;
    ECAM_MEMORY_BARRIER();
    pair->armed = 1u;
    return ECAM_SWITCH_OK;
}

int ecam_switch_cancel(ecam_switch_pair *pair)
{
    uint32_t before;
    if (pair == NULL) {
        return ECAM_SWITCH_E_NULL;
    }
    /* The count is read before the flag and again after clearing it: an interrupt that switches
     * anywhere in between changes the count, and one after the clear sees nothing armed. */
    before = pair->switches;
    if (pair->armed == 0u) {
        return pair->switches != before ? ECAM_SWITCH_E_SWITCHED : ECAM_SWITCH_E_NO_PENDING;
    }
    pair->armed = 0u;
    ECAM_MEMORY_BARRIER();
    return pair->switches != before ? ECAM_SWITCH_E_SWITCHED : ECAM_SWITCH_OK;
}

/* The switch at `boundary` (the running table's master there): place the pending table's
 * coordinates (ecam_table_pair.h) and return its master for `master`. */
static uint64_t ecam_switch_take_over(ecam_switch_pair *pair, uint64_t boundary, int64_t master)
{
    const ecam_table *next = pair->pending;
    const uint32_t mode = pair->mode;
    /* the slave at the boundary, on the running table: what a relative slave continues from */
    const uint32_t at = (uint32_t)ecam_table_position(pair->running, ecam_switch_s64(boundary)) +
                        pair->offset;
    const uint64_t where = boundary + pair->origin;
    uint64_t local;
    /* X = master - zero + MasterOffset, Y = CAM(X) + SlaveOffset + base (ecam_table_pair.h) */
    pair->origin = ((mode & ECAM_SWITCH_MASTER_RELATIVE) != 0u ? where : 0u) - pair->pending_master;
    pair->offset = ((mode & ECAM_SWITCH_SLAVE_RELATIVE) != 0u ? at : 0u) + pair->pending_slave;
    ecam_switch_run(pair, next);
    pair->boundary = where;
    local = (uint64_t)master - pair->origin;
    pair->window = ecam_switch_window(next, local);
    pair->state = ecam_switch_state(next, local, pair->window);
    pair->armed = 0u;
    ECAM_MEMORY_BARRIER();
    pair->switches = pair->switches + 1u;
    return local;
}

/* The cold path: the first sample, a sample outside the last one's period, or one after a
 * profile that does not repeat has ended. Returns the running table's master for `master`. */
static uint64_t ecam_switch_cross(ecam_switch_pair *pair, int64_t master, uint64_t local, int *rc)
{
    const ecam_table *t = pair->running;
    uint64_t boundary;
    if (pair->state == ECAM_SWITCH_FIRST) {
        /* no previous sample, so no boundary crossed: place the window */
        pair->window = ecam_switch_window(t, local);
        pair->state = ecam_switch_state(t, local, pair->window);
        return local;
    }
    if (pair->state == ECAM_SWITCH_ENDED) {
        /* the profile ended at an earlier sample: a pending table takes over here, at the
         * current master position */
        if (pair->armed != 0u) {
            *rc = ECAM_SWITCH_DONE;
            return ecam_switch_take_over(pair, local, master);
        }
        pair->state = ecam_switch_state(t, local, pair->window);
        return local;
    }
    /* left the period [window, window + M): forwards past its end or backwards below its start
     * (the signed distance tells which while the master moves less than 2^63 per sample) */
    boundary = ecam_switch_s64(local - pair->window) >= 0 ? pair->window + (uint64_t)t->master_counts
                                                          : pair->window;
    if (pair->armed != 0u) {
        *rc = ECAM_SWITCH_DONE;
        return ecam_switch_take_over(pair, boundary, master);
    }
    pair->window = ecam_switch_window(t, local);
    pair->state = ecam_switch_state(t, local, pair->window);
    return local;
}

int ecam_switch_step(ecam_switch_pair *pair, int64_t master, int32_t *position, int32_t *slope)
{
    const ecam_table *t;
    uint64_t local;
    int rc = ECAM_SWITCH_OK;
    if (pair == NULL || pair->running == NULL) {
        if (position != NULL) {
            *position = ECAM_INVALID;
        }
        if (slope != NULL) {
            *slope = ECAM_INVALID;
        }
        return pair == NULL ? ECAM_SWITCH_E_NULL : ECAM_SWITCH_E_NOT_ENGAGED;
    }
    local = (uint64_t)master - pair->origin;
    /* hot path: one compare while the master stays in the last sample's period */
    if (pair->state != ECAM_SWITCH_TRACKING || (local - pair->window) >= pair->span) {
        local = ecam_switch_cross(pair, master, local, &rc);
    }
    t = pair->running;
    /* A periodic table without a net stroke repeats exactly, so it is looked up inside the
     * period the pair already knows: the same bits (FORMAT.md step 1), without the table's wrap
     * of a master outside [0, M). A net stroke counts whole periods: it keeps the master. */
    ecam_table_lookup(t, ecam_switch_s64(pair->repeat != 0u ? local - pair->window : local), position, slope);
    if (position != NULL) {
        *position = ecam_switch_s32((uint32_t)*position + pair->offset);
    }
    return rc;
}

int ecam_switch_pending(const ecam_switch_pair *pair)
{
    return (pair != NULL && pair->armed != 0u) ? 1 : 0;
}

uint32_t ecam_switch_count(const ecam_switch_pair *pair)
{
    return pair == NULL ? 0u : pair->switches;
}

int64_t ecam_switch_boundary(const ecam_switch_pair *pair)
{
    return pair == NULL ? 0 : ecam_switch_s64(pair->boundary);
}

const char *ecam_switch_status_name(int status)
{
    switch (status) {
    case ECAM_SWITCH_OK:
        return "ECAM_SWITCH_OK";
    case ECAM_SWITCH_DONE:
        return "ECAM_SWITCH_DONE";
    case ECAM_SWITCH_E_NULL:
        return "ECAM_SWITCH_E_NULL";
    case ECAM_SWITCH_E_NOT_ENGAGED:
        return "ECAM_SWITCH_E_NOT_ENGAGED";
    case ECAM_SWITCH_E_TABLE:
        return "ECAM_SWITCH_E_TABLE";
    case ECAM_SWITCH_E_MODE:
        return "ECAM_SWITCH_E_MODE";
    case ECAM_SWITCH_E_ARMED:
        return "ECAM_SWITCH_E_ARMED";
    case ECAM_SWITCH_E_NO_PENDING:
        return "ECAM_SWITCH_E_NO_PENDING";
    case ECAM_SWITCH_E_MASTER_RANGE:
        return "ECAM_SWITCH_E_MASTER_RANGE";
    case ECAM_SWITCH_E_SWITCHED:
        return "ECAM_SWITCH_E_SWITCHED";
    default:
        return "ECAM_SWITCH_UNKNOWN";
    }
}
