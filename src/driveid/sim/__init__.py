"""Simulators: the exact 1-DOF oscillator (and, later, the lumped multi-body drive)."""

from driveid.sim.oscillator import FreeDecay, OscillatorParams, measure, simulate_free_decay

__all__ = ["OscillatorParams", "FreeDecay", "simulate_free_decay", "measure"]
