"""Simulators: the exact 1-DOF oscillator, the lumped multi-body drive, LuGre stick-slip.

Presets of the thesis's plants are in :mod:`driveid.sim.presets`, TOML configs in
:mod:`driveid.sim.config`.
"""

from driveid.sim.batch import FreeDecayBatch, simulate_drive_batch, simulate_free_decay_batch
from driveid.sim.drive import (
    BacklashLink,
    BodyParams,
    DriveParams,
    DriveResult,
    PDFeedback,
    ShaftLink,
    simulate_drive,
)
from driveid.sim.lugre import LuGreResult, simulate_lugre_oscillator
from driveid.sim.oscillator import FreeDecay, OscillatorParams, measure, simulate_free_decay

__all__ = [
    "OscillatorParams",
    "FreeDecay",
    "simulate_free_decay",
    "measure",
    "BodyParams",
    "ShaftLink",
    "BacklashLink",
    "PDFeedback",
    "DriveParams",
    "DriveResult",
    "FreeDecayBatch",
    "simulate_drive",
    "simulate_drive_batch",
    "simulate_free_decay_batch",
    "LuGreResult",
    "simulate_lugre_oscillator",
]
