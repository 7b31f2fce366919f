"""Friction tests: ramps, steps, speed plateaus, operating records (thesis §2.1.1).

* :mod:`~driveid.identify.friction.idim` (noise model in ``_idim_noise``) — inverse dynamic
  model by least squares; :mod:`~driveid.identify.friction.online` — its recursive form;
* :mod:`~driveid.identify.friction.friction_map` — the friction–speed map from plateaus;
* :mod:`~driveid.identify.friction.breakaway`, :mod:`~driveid.identify.friction.static_tests`
  — breakaway friction, presliding, static stiffness;
* :mod:`~driveid.identify.friction.square_wave` — DC-biased square-wave (step) runs;
* :mod:`~driveid.identify.friction.position_friction` — friction periodic in position.

Imports only :mod:`driveid.identify.core`.
"""
