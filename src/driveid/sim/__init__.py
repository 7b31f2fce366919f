"""Simulators: the exact 1-DOF oscillator and the lumped multi-body drive."""

from driveid.sim.drive import (
    BacklashLink,
    BodyParams,
    DriveParams,
    DriveResult,
    FreeDecayBatch,
    PDFeedback,
    ShaftLink,
    simulate_drive,
    simulate_free_decay_batch,
)
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
    "simulate_free_decay_batch",
]
