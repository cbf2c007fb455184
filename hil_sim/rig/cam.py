"""The scene's cam: loaded and compiled to its table once per cam content and table format,
and its acceleration sampled over one period (for the excitation and resonance figures)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import ecam
from ecam.camfile import read_bounded
from ecam.errors import InputError
from ecam.profile import CamProfile
from ecam.table import CamTable
from hil_sim.scene import Scene

_RESONANCE_SAMPLES = 4096  # samples of one cam period for its harmonic spectrum
_CACHE_SIZE = 8


@dataclass(frozen=True)
class CompiledCam:
    """A scene's cam profile, its table and the slave scaling the table was built with.

    Attributes
    ----------
    profile : ecam.CamProfile
    table : ecam.CamTable
        Immutable, so one compiled table serves every run of the same cam and format.
    scale : float
        Slave counts per slave unit.
    """

    profile: CamProfile
    table: CamTable
    scale: float


_compiled: dict = {}  # (cam content, table format) -> CompiledCam


def compile_cam(scene: Scene) -> CompiledCam:
    """Load and compile the scene's cam, once per cam content and table format."""
    spec = scene.cam
    try:
        # The cam file's bytes (read with the cam loader's bounds: a 2 GB file or /proc/kmsg is
        # refused before it is hashed), or an in-memory cam as the cam file it would write.
        content = (spec.profile.to_toml() if spec.profile is not None
                   else read_bounded(spec.file, "cam file"))
        key = (content, spec.interp, spec.points, spec.tolerance, spec.master_counts,
               spec.slave_counts_per_unit)
    except (OSError, InputError):
        key = None  # loading the cam reports it; a law without a file name is compiled each time
    if key in _compiled:
        return _compiled[key]
    result = _compile_uncached(scene)
    if key is not None:
        if len(_compiled) >= _CACHE_SIZE:
            _compiled.pop(next(iter(_compiled)))
        _compiled[key] = result
    return result


def _compile_uncached(scene: Scene) -> CompiledCam:
    profile = scene.cam.load_profile()
    table = ecam.compile_table(profile, scene.cam.table_spec(profile))
    return CompiledCam(profile, table, float(table.certificate.slave_counts_per_unit))


def cam_acceleration(profile: CamProfile) -> np.ndarray:
    """The cam's slave acceleration [slave units / master unit^2] over one period, sampled."""
    x = np.arange(_RESONANCE_SAMPLES) * (profile.master_period / _RESONANCE_SAMPLES)
    return profile(x, 2)


def cam_spectrum(profile: CamProfile) -> np.ndarray:
    """|FFT| of the cam's slave acceleration over one period, harmonics 0..n/2."""
    return np.abs(np.fft.rfft(cam_acceleration(profile)))
