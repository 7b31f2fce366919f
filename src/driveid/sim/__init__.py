"""Simulators: the exact 1-DOF oscillator, the lumped multi-body drive, LuGre stick-slip.

Presets of the thesis's plants are in :mod:`driveid.sim.presets`, TOML configs in
:mod:`driveid.sim.config`.
"""

from __future__ import annotations

from driveid._lazy_exports import lazy_exports

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


__getattr__, __dir__ = lazy_exports('driveid.sim', globals(), _EXPORTS)


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
