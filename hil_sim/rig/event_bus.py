"""The drive-side events' SDO frames in the bus budget (issue 23).

A drive-side switch is sent as SDO writes (:func:`hil_sim.events._drive_commands`): the table
downloaded segmented into 0x2000 (CiA 301 segmented download: an initiate request and response,
then a request and a response per 7 bytes of data; every SDO frame carries 8 data bytes) and the
cam slot's objects written expedited (a request and a response each; a 64-bit object segmented:
the initiate and two segments, of 7 and 1 bytes, each answered: 6 frames). The rig's lock-step
controller sends them in the cycle the event is requested in and the drive has them at once; on
a real bus they are the lowest-priority frames
and go in the bits the cyclic traffic leaves (:meth:`hil_sim.bus.BusLoad.queue_frame` counts them
so, cycle by cycle). This module says what that means for each event:

* a queued switch or offset (``period_end``, ``master_position``) must be in the drive before it
  activates:
  when its frames go out only in or after the cycle it activates in, the switch would come late
  on a real bus, and the ``bus_load`` check's value becomes the load the cycles between the
  request and the activation would need to carry it in time (the cyclic peak plus the transfer's
  bits spread over them), so a switch that pushes those cycles over the limit fails;
* an ``immediate`` switch or offset and a ``cam_out`` act when their last frame arrives: the
  detail says how many cycles after the request that is.
"""

from __future__ import annotations

import math

__all__ = ["event_sdo"]


def event_sdo(run, bus: dict) -> tuple[str, float | None]:
    """The events' SDO transfers of a run over the bus, in words, and the load [% of a cycle's
    bits] the busiest late queued switch would need (None when every one is in time).

    Parameters
    ----------
    run : hil_sim.rig.run.PreparedRun
    bus : dict
        The record's bus summary (:meth:`hil_sim.bus.BusLoad.summary`).
    """
    sdo = bus.get("event_sdo")
    if not sdo:
        return "", None
    node = run.scene.drive.node_id
    events = run.plan.events
    activation = ({s.event.index: (s.event.activation, s.active_s) for s in events.switches}
                  if events is not None else {})
    cycle_s, lead = run.plan.cycle_s, run.scene.master.lead_cycles
    budget = bus["budget_bits"]
    parts, needed = [], None
    for transfer in sdo["transfers"]:
        if transfer["node"] != node:
            continue
        queued, sent = transfer["queued_cycle"], transfer["sent_cycle"]
        kind, active_s = activation.get(transfer["event"], ("cam_out", None))
        text = f"event[{transfer['event']}] {transfer['frames']} SDO frames ({transfer['bits']} bits)"
        text += f" in cycles {queued}..{sent}" if sent is not None else f" from cycle {queued}, not all sent"
        if kind in ("period_end", "master_position") and active_s is None:
            text += ", never activated (superseded or not reached)"
        elif kind in ("period_end", "master_position"):
            act = math.ceil(active_s / cycle_s - lead - 1e-9)  # the cycle whose set point switches
            if sent is None or sent >= act:
                cycles = max(act - queued, 1)
                need = 100.0 * (bus["peak_bits"] + math.ceil(transfer["bits"] / cycles)) / budget
                needed = need if needed is None else max(needed, need)
                text += (f", past its activation in cycle {act}: carrying it in time needs "
                         f"{need:.4g} % of the cycles between")
            else:
                text += f", before its activation in cycle {act}"
        elif sent is not None:
            text += f": it acts {sent - queued + 1} cycle(s) after the request"
        parts.append(text)
    return "; ".join(parts), needed
