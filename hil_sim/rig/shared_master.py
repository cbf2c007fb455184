"""One master position PDO for every drive-side axis of a machine (``[bus] master_position_pdo =
"shared"``): the controller sends the virtual master's position once per SYNC on one COB-ID and
every drive-side drive consumes it with its RPDO3 (CiA 301 7.2.2: a PDO has one producer and any
number of consumers; each consumer's RPDO communication parameter 1400h..15FFh names the
COB-ID), instead of one RPDO per axis.

The drives then receive the very same value. The rig's drive has no master offset of its own, so
the axes that share the PDO must need the same master position every cycle: the same phase
against the virtual master and the same master counts per period in their tables (the value on
the wire, :func:`hil_sim.rig.plan.wire_set_points`, compared cycle by cycle). Where they do, every
axis runs bit for bit as with a PDO of its own, and the bus carries one frame less per SYNC for
each further axis.
"""

from __future__ import annotations

import numpy as np

from ecam.errors import InputError
from hil_sim.rig.plan import wire_set_points

#: CiA 301 pre-defined connection set: RPDO3's COB-ID is 0x400 + node id.
RPDO3_COB_ID = 0x400


def shared_master_cob_id(axes: list) -> int | None:
    """The COB-ID of the shared master position PDO for a machine's axes (:class:`AxisRun`),
    or None when the machine sends one per axis (or has no drive-side axis).

    It is the first drive-side axis's own RPDO3 COB-ID (0x400 + its node id): that drive keeps
    its set-up, the others are pointed at it.

    Raises
    ------
    InputError
        A drive-side axis needs another master position than the first one in some cycle.
    """
    drive_side = [a for a in axes if a.run.scene.cam_mode == "drive"]
    if not drive_side or drive_side[0].run.scene.bus.master_position_pdo != "shared":
        return None
    first = drive_side[0].run
    reference = wire_set_points(first.plan, drive_side=True)[0]
    for axis in drive_side[1:]:
        scene = axis.run.scene
        values = wire_set_points(axis.run.plan, drive_side=True)[0]
        differ = np.flatnonzero(values != reference)
        if differ.size:
            k = int(differ[0])
            raise InputError(
                f"bus.master_position_pdo: 'shared' should carry one master position for every "
                f"drive-side axis, but axis {scene.name} needs {int(values[k])} counts where "
                f"axis {first.scene.name} needs {int(reference[k])} (cycle {k}; phase "
                f"{scene.phase:g} against {first.scene.phase:g}, master_counts "
                f"{axis.run.cam.table.master_counts} against {first.cam.table.master_counts}): "
                "give them the same phase and master counts, or 'per_axis'")
    return RPDO3_COB_ID + first.scene.drive.node_id
