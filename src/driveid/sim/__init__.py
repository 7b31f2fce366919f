"""Simulators: the exact 1-DOF oscillator, the lumped multi-body drive, LuGre stick-slip.

Presets of the thesis's plants are in :mod:`driveid.sim.presets`, TOML configs in
:mod:`driveid.sim.config`.
"""

from __future__ import annotations

import importlib
from typing import Any

# Public name -> module; imported on first use (PEP 562) so that reading a preset's names or
# parameter types does not load the numba engines (`driveid pho run --help` stays fast).
_EXPORTS = {
    "FreeDecayBatch": "driveid.sim.batch",
    "simulate_drive_batch": "driveid.sim.batch",
    "simulate_free_decay_batch": "driveid.sim.batch",
    "BacklashLink": "driveid.sim.drive_types",
    "BodyParams": "driveid.sim.drive_types",
    "DriveParams": "driveid.sim.drive_types",
    "DriveResult": "driveid.sim.drive_types",
    "PDFeedback": "driveid.sim.drive_types",
    "ShaftLink": "driveid.sim.drive_types",
    "simulate_drive": "driveid.sim.drive",
    "LuGreResult": "driveid.sim.lugre",
    "simulate_lugre_oscillator": "driveid.sim.lugre",
    "FreeDecay": "driveid.sim.oscillator",
    "OscillatorParams": "driveid.sim.oscillator",
    "measure": "driveid.sim.oscillator",
    "simulate_free_decay": "driveid.sim.oscillator",
}


def __getattr__(name: str) -> Any:
    """Import a public simulator name on first use."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'driveid.sim' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


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
