"""Forced and driven responses: sine runs, force–displacement loops, FRFs, transfer functions.

* :mod:`~driveid.identify.forced.forced`, :mod:`~driveid.identify.forced.forced_friction`,
  :mod:`~driveid.identify.forced.sine_fit` — J, C, K and friction from sinusoidal runs;
* :mod:`~driveid.identify.forced.loops` — backlash and hysteresis loops;
* :mod:`~driveid.identify.forced.frf` — frequency response from sine runs;
* :mod:`~driveid.identify.forced.transfer` (models in ``transfer_models``) — command-to-speed
  drive tests (PRBS, multisine), the two-mass drive.

Imports :mod:`driveid.identify.core` and :mod:`driveid.identify.pho` (the loop-delay factors).
"""
