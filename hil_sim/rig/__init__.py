"""The software-in-the-loop rig: a scene in, a tracking report out.

One run, in order (:func:`run_scene`, in :mod:`hil_sim.rig.run`):

1. **Cam and table** (:mod:`~hil_sim.rig.cam`). The scene's cam is loaded and compiled
   (:func:`ecam.compile_table`), once per cam content and table format.
2. **Model.** The mechanics and the cam's excitation at the master speed go to
   :class:`hil_sim.control.ServoAxis`, which picks the simplest faithful plant
   (:func:`hil_sim.plant.choose_model`); the report says which and why.
3. **Master plan** (:mod:`~hil_sim.rig.plan`). The master's motion (constant speed,
   jerk-limited start/stop, or a cam-in planned with ruckig) is sampled for every cycle up
   front: it does not depend on the slave. So are the set points.
4. **Set-up** (:mod:`~hil_sim.rig.network`). A controller (a canopen ``RemoteNode`` on its own
   virtual bus, :class:`LockstepMaster`) boots the :class:`~hil_sim.drive.VirtualDrive`,
   configures it by SDO (interpolation period, following-error window, mode; drive-side: the
   table download and activation), starts it (NMT) and enables it (CiA 402 controlword by
   RPDO).
5. **Lock-step over the virtual bus** (:mod:`~hil_sim.rig.loop`). Each cycle: the RPDO with
   the set point, the SYNC, the drive handles both (runs its control loop one period and
   answers with its TPDOs), the controller reads the TPDOs. Faults (lost or late frames, SYNC
   jitter) are applied here, from a seeded generator.
6. **Report** (:mod:`~hil_sim.rig.analysis`). Following error, load-side tracking error,
   coupling torque against its rating, wind-up, torsional resonance against the cam's
   harmonics (the coupling checks of :mod:`ecam.mechanics`), bus load, faults, torque
   saturation: each a check with a limit. :mod:`~hil_sim.rig.plot` draws them.

Nothing waits on a clock and no thread runs, so the same scene gives the same report, bit for
bit. :func:`find_max_speed` (:mod:`~hil_sim.rig.search`) bisects the master speed for the
highest one that passes.
"""

from hil_sim.rig.network import LockstepMaster
from hil_sim.rig.run import drive_for_scene, run_scene, scene_drive_options
from hil_sim.rig.search import find_max_speed

__all__ = ["LockstepMaster", "drive_for_scene", "find_max_speed", "run_scene", "scene_drive_options"]
