/*
 * ecam_table_pair.h - a running and a pending cam table: the pending one, once armed, takes over
 * exactly where the master crosses the running table's period boundary (queued table switching).
 *
 * What it is for: a product change-over on a running machine. The main loop arms the next
 * table; the control interrupt keeps stepping the pair with the master position, and the pair
 * switches by itself at the first period boundary the master crosses, in the sample where it
 * crosses it, never one count early or late. Rockwell's pending cam ("takes effect when the
 * master passes the profile's end"), TwinCAT's activation "next cam cycle" and CODESYS, which
 * places a newly selected cam "exactly at the end of the previous one", do the same.
 *
 * Names: the issue calls this ecam_table_pair; that type name is the double buffer of
 * ecam_table.h (ecam_pair_load/acquire: a new table that takes over at once, TwinCAT's
 * "instantaneous"). This file's type is ecam_switch_pair and its functions ecam_switch_*.
 *
 * Coordinates, as PLCopen defines them per axis (PLCopen TC2, Function Blocks for Motion
 * Control, Version 2.0 (formerly Part 1 and Part 2), 2011: MC_CamTableSelect inputs
 * MasterAbsolute / SlaveAbsolute; MC_CamIn inputs MasterOffset, SlaveOffset, StartMode), in the
 * wording of CODESYS SM3_Basic (online help, "Function Blocks: MC_CamTableSelect and MC_CamIn"),
 * which spells out a switch, and as ecam's own `ecam check A --then B` (ecam/cam_join.py)
 * predicts it:
 *
 *   offsets      MC_CamIn's MasterOffset and SlaveOffset, given at the engagement and again with
 *                each switch (a switch is a new MC_CamIn): the table is looked up at
 *                X = master - zero + MasterOffset ("X = MasterScaling * MasterPosition +
 *                MasterOffset", scaling 1) and the slave is Y = CAM(X) + SlaveOffset + base
 *                ("Y = SlaveScaling * CAM(X) + SlaveOffset"), with zero and base as below. The
 *                engagement is StartMode absolute (zero = 0, base = 0); for a relative start pass
 *                MasterOffset = -master and SlaveOffset = the slave's position.
 *   master absolute  zero = 0: the pending table "is started at the current master position"
 *                (CODESYS), wherever that falls in its period. Refused for a pending table that
 *                does not repeat (ECAM_SWITCH_E_MASTER_RANGE: CODESYS reports
 *                SMC_CI_MASTER_OUT_OF_SCALE when the master falls outside its range; the
 *                boundaries of a running periodic table lie at every multiple of its period).
 *   master relative  zero = the boundary: it "sets the zero point of the master to ... the
 *                position at the end of the previous cam", which "allows the new cam to be
 *                connected exactly to the previous one" (CODESYS); Beckhoff (MC_StartMode): "the
 *                origin of the cam plate coordinate system is at the axis position ... at the time
 *                of coupling or cam plate switching". The table is entered at X = MasterOffset,
 *                which must lie in the range of a table that does not repeat ("The
 *                MasterAbsolute=FALSE mode may be used only if the value 0 is in the master value
 *                range", CODESYS; ECAM_SWITCH_E_MASTER_RANGE otherwise). A master crossing the
 *                boundary backwards enters the table below that: a periodic one wraps to its
 *                period end, one that does not repeat holds its start.
 *   slave absolute   base = 0: "the cam is evaluated independent of the current position of the
 *                slave. This can lead to jumps" (CODESYS, StartMode absolute).
 *   slave relative   base = the slave's position at the boundary (the running table's position
 *                there, plus its offset): "The position that the slave has after the end of the
 *                previous cycle is added as a slave offset to the new evaluations of the cam"
 *                (CODESYS, StartMode relative). With SlaveOffset 0 the switch is continuous in
 *                position whenever the pending table is 0 where it is entered (a cam that starts
 *                at 0, entered with the master relative), the condition
 *                `ecam check A --then B --slave relative` checks.
 *
 * The boundary: a periodic running table's periods are [origin + k M, origin + (k+1) M) with
 * origin its master 0 (the master position where its lookup sees 0). The pair remembers the
 * period of the last sample; a sample in another period has crossed the boundary between them,
 * the end of the period forwards (master >= origin + (k+1) M: the boundary is that position) or
 * its start backwards (master < origin + k M: the boundary is origin + k M). The pending table
 * then governs this sample already: forwards it takes over at the boundary count itself,
 * backwards at the count below it, so each table keeps the half-open period it owns. A jump over
 * several periods switches at the first boundary crossed. A running table that does not repeat
 * has one "period", its master range [origin, origin + M); leaving it ends the profile (the slave
 * holds its end position) and a pending table takes over at the end crossed; armed while the
 * profile has already ended, it takes over at the next sample, at that sample's master position
 * ("the current master position", CODESYS).
 *
 * Arithmetic: integers only, deterministic, no allocation, no floating point. Master positions
 * are int64 counts taken modulo 2^64 (a wrapping counter extended to 64 bits), slave positions
 * int32 counts modulo 2^32 (CiA 402 positions roll over): offsets add modulo 2^32, exactly as the
 * Python SwitchPair (ecam/table_pair.py) computes them, bit for bit. The first sample of a period
 * costs a 64-bit division (the period it is in); the others one compare and the table's lookup.
 *
 * Concurrency (single core; the main loop at a lower priority than the interrupt that steps):
 *   main loop:  ecam_switch_engage(&pair, &a, master_offset, slave_offset) before the interrupt
 *               steps the pair; later ecam_switch_arm(&pair, &b, mode, master_offset,
 *               slave_offset), ecam_switch_cancel(&pair).
 *   interrupt:  rc = ecam_switch_step(&pair, master, &position, &slope) once per cycle.
 * Arming writes the pending table and its mode, then the armed flag (volatile stores in this
 * order); the interrupt reads the pending table only when the flag is set, and it alone changes
 * the running table (at a switch, which clears the flag). The tables must stay initialised and
 * unchanged while the pair refers to them: the replaced table (and its blob) may be reused once
 * ecam_switch_count() has changed since it was replaced. For a reader on another core define
 * ECAM_MEMORY_BARRIER() (e.g. __DMB()), as for ecam_table_pair.
 */
#ifndef ECAM_TABLE_PAIR_H
#define ECAM_TABLE_PAIR_H

#include <stdint.h>

#include "ecam_table.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The mode of a switch (ecam_switch_arm): PLCopen MasterAbsolute / SlaveAbsolute FALSE. */
#define ECAM_SWITCH_MASTER_RELATIVE 1u
#define ECAM_SWITCH_SLAVE_RELATIVE 2u

/*
 * Results. Every refusal has its own code, distinct from ecam_table.h's codes, so a log line
 * names it unambiguously (ecam_switch_status_name).
 */
typedef enum ecam_switch_status {
    ECAM_SWITCH_OK = 0,
    ECAM_SWITCH_DONE = 1,               /* ecam_switch_step: the pending table took over here */
    ECAM_SWITCH_E_NULL = -40,           /* a NULL pair or table */
    ECAM_SWITCH_E_NOT_ENGAGED = -41,    /* no running table: ecam_switch_engage first */
    ECAM_SWITCH_E_TABLE = -42,          /* the table is not ready (ecam_table_init failed) */
    ECAM_SWITCH_E_MODE = -43,           /* a mode bit other than the two above */
    ECAM_SWITCH_E_ARMED = -44,          /* a switch is already pending: cancel it first */
    ECAM_SWITCH_E_NO_PENDING = -45,     /* ecam_switch_cancel: nothing is armed */
    ECAM_SWITCH_E_MASTER_RANGE = -46,   /* a table that does not repeat, entered outside its range */
    ECAM_SWITCH_E_SWITCHED = -47        /* ecam_switch_cancel: too late, the switch happened */
} ecam_switch_status;

/*
 * The pair. Treat the members as private. All zero (static storage, or ecam_switch_init) is
 * "not engaged": ecam_switch_step returns ECAM_SWITCH_E_NOT_ENGAGED and ECAM_INVALID outputs.
 */
typedef struct ecam_switch_pair {
    const ecam_table *running;          /* the table looked up; NULL until engaged */
    const ecam_table *volatile pending; /* read by the interrupt only while armed */
    volatile uint32_t armed;            /* 1: pending takes over at the next boundary */
    volatile uint32_t mode;             /* ECAM_SWITCH_* bits of the pending switch */
    volatile uint32_t switches;         /* switches done since the engagement (wraps) */
    uint64_t pending_master;  /* the pending switch's MasterOffset, as uint64 bits */
    uint64_t origin;      /* master position where the running table's lookup sees 0 (mod 2^64) */
    uint64_t window;      /* the running table's master at the start of the last sample's period */
    uint64_t boundary;    /* master position of the last switch (mod 2^64) */
    uint32_t pending_slave;   /* the pending switch's SlaveOffset, as uint32 bits */
    uint32_t offset;      /* added to the running table's position (mod 2^32) */
    uint64_t span;        /* the running table's master_counts (no pointer chase per sample) */
    uint8_t state;        /* 0 tracking the window; 1 no sample yet (ECAM_SWITCH_FIRST); 2 a
                             running table that does not repeat was left (ECAM_SWITCH_ENDED) */
    uint8_t repeat;       /* 1: the running table repeats exactly (periodic, no net stroke) */
} ecam_switch_pair;

/* Not engaged, nothing pending (the all-zero state). */
void ecam_switch_init(ecam_switch_pair *pair);

/*
 * Engage `table` (MC_CamIn, StartMode absolute): looked up at master + master_offset, its
 * position plus slave_offset. Clears any pending switch and the switch count. Not while an
 * interrupt steps the pair. ECAM_SWITCH_OK, ECAM_SWITCH_E_NULL or ECAM_SWITCH_E_TABLE (the pair
 * is then left as it was).
 */
int ecam_switch_engage(ecam_switch_pair *pair, const ecam_table *table, int64_t master_offset,
                       int32_t slave_offset);

/*
 * Arm `table` to take over at the next period boundary the master crosses, with `mode` (0, or
 * ECAM_SWITCH_MASTER_RELATIVE and/or ECAM_SWITCH_SLAVE_RELATIVE) and the new MC_CamIn's
 * MasterOffset and SlaveOffset (0, 0 for none). Refusals, checked in this order:
 * ECAM_SWITCH_E_NULL, ECAM_SWITCH_E_NOT_ENGAGED, ECAM_SWITCH_E_ARMED, ECAM_SWITCH_E_TABLE,
 * ECAM_SWITCH_E_MODE, ECAM_SWITCH_E_MASTER_RANGE; a refusal changes nothing.
 */
int ecam_switch_arm(ecam_switch_pair *pair, const ecam_table *table, unsigned mode,
                    int64_t master_offset, int32_t slave_offset);

/*
 * Withdraw the armed switch: ECAM_SWITCH_OK (it will not happen), ECAM_SWITCH_E_NO_PENDING
 * (nothing was armed), ECAM_SWITCH_E_SWITCHED (the interrupt switched first: the table is
 * running), ECAM_SWITCH_E_NULL.
 */
int ecam_switch_cancel(ecam_switch_pair *pair);

/*
 * One sample: the slave position (the running table's, plus the offset, modulo 2^32) and the
 * slope (Q16 slave counts per master count, the running table's) at `master` (any int64 counts);
 * either output pointer may be NULL. Returns ECAM_SWITCH_OK, ECAM_SWITCH_DONE when the pending
 * table took over at this sample (the outputs are already the new table's), or
 * ECAM_SWITCH_E_NULL / ECAM_SWITCH_E_NOT_ENGAGED with both outputs ECAM_INVALID.
 */
int ecam_switch_step(ecam_switch_pair *pair, int64_t master, int32_t *position, int32_t *slope);

/* 1 while a switch is armed (it has not happened yet), else 0. */
int ecam_switch_pending(const ecam_switch_pair *pair);

/* Switches done since the engagement (modulo 2^32). */
uint32_t ecam_switch_count(const ecam_switch_pair *pair);

/* The master position (int64 counts) of the boundary of the last switch; 0 before any. */
int64_t ecam_switch_boundary(const ecam_switch_pair *pair);

/* Readable name of a result ("ECAM_SWITCH_E_ARMED", ...); "ECAM_SWITCH_UNKNOWN" otherwise. */
const char *ecam_switch_status_name(int status);

#ifdef __cplusplus
}
#endif

#endif /* ECAM_TABLE_PAIR_H */
